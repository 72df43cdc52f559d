"""YAML decoders: at most two warm child processes (:mod:`pickstop.api.yaml_child`) that
decode one document at a time each, under a time limit.

A child decodes documents one after another until it is killed or stops: a document that
outlasts its time is answered by killing the child (the next one starts fresh), and so is one
after which the child cannot go on (it ran out of memory, it crashed). Nothing of a document
lives on in the API's interpreter, and a warm child answers a small document in about a
millisecond where a new interpreter takes about 80.

The protocol on the child's stdin and stdout: each message is an 8-byte big-endian length and
that many bytes: the document as UTF-8 in, ``{"doc": ...}`` or ``{"error": "..."}`` as JSON
out. A child started in one process is never used by a process forked from it.
"""

from __future__ import annotations

import atexit
import os
import select
import struct
import subprocess
import sys
import threading
import time

#: Documents a child decodes before it is replaced (its allocator's memory is returned).
RECYCLE_AFTER = 1000
_HEAD = struct.Struct(">Q")


class DecodeTimeout(Exception):
    """The document outlasted its time: its child was killed."""


class ChildLost(Exception):
    """The child stopped before it answered (out of memory, a crash)."""


class _Child:
    """One warm decoder process."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "pickstop.api.yaml_child", "--serve"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        self.served = 0

    def ask(self, data: bytes, seconds: float) -> bytes:
        """The child's answer to document ``data`` within ``seconds``; raises
        :class:`DecodeTimeout` (the child is killed) or :class:`ChildLost`."""
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(_HEAD.pack(len(data)) + data)
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise ChildLost from None
        deadline = time.monotonic() + seconds
        (size,) = _HEAD.unpack(self._read(_HEAD.size, deadline))
        out = self._read(size, deadline)
        self.served += 1
        return out

    def _read(self, n: int, deadline: float) -> bytes:
        assert self.proc.stdout is not None
        fd, parts, got = self.proc.stdout.fileno(), [], 0
        while got < n:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                self.kill()
                raise DecodeTimeout
            chunk = os.read(fd, min(n - got, 1 << 20))
            if not chunk:
                self.kill()
                raise ChildLost
            parts.append(chunk)
            got += len(chunk)
        return b"".join(parts)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for pipe in (self.proc.stdin, self.proc.stdout):
            if pipe is not None:
                pipe.close()


class YamlDecoders:
    """At most ``slots`` documents decode at once, each in a warm child of its own."""

    def __init__(self, slots: int = 2) -> None:
        self.slots = slots
        self._lock = threading.Lock()
        self._reset()

    def _reset(self) -> None:
        self._pid = os.getpid()
        self._free = threading.BoundedSemaphore(self.slots)
        self._idle: list[_Child] = []

    def decode(self, data: bytes, seconds: float) -> bytes:
        """The answer of a child to document ``data`` (UTF-8) within ``seconds``; raises
        :class:`DecodeTimeout` or :class:`ChildLost`. A child found gone before it was asked
        (it stopped while idle) is replaced once."""
        with self._lock:
            if self._pid != os.getpid():  # forked: the parent's children are not ours
                self._reset()
            free = self._free
        with free:
            return self._ask(self._take(), data, seconds, retry=True)

    def _ask(self, child: _Child, data: bytes, seconds: float, retry: bool) -> bytes:
        warm = child.served > 0
        try:
            out = child.ask(data, seconds)
        except ChildLost:
            child.kill()
            if warm and retry:  # it stopped while idle: a fresh one answers
                return self._ask(_Child(), data, seconds, retry=False)
            raise
        self._give(child)
        return out

    def _take(self) -> _Child:
        with self._lock:
            while self._idle:
                child = self._idle.pop()
                if child.alive():
                    return child
                child.kill()
        return _Child()

    def _give(self, child: _Child) -> None:
        if child.served >= RECYCLE_AFTER or not child.alive():
            child.kill()
            return
        with self._lock:
            if self._pid == os.getpid():
                self._idle.append(child)
                return
        child.kill()

    def close(self) -> None:
        """Stop the idle children (those decoding stop when their answer is read)."""
        with self._lock:
            idle, self._idle = self._idle, []
        for child in idle:
            child.kill()

    def pids(self) -> list[int]:
        """The idle children's process ids (for tests and diagnostics)."""
        with self._lock:
            return [c.proc.pid for c in self._idle]


#: The process's decoders (children start on first use).
DECODERS = YamlDecoders()
atexit.register(DECODERS.close)
