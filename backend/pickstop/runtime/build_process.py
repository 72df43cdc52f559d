"""A database build of the job runner, in a child process with a process group of its own.

A build runs pools of worker processes (:func:`pickstop.reach.build.run_local`); stopped from
another thread (a cancel, a deadline, the service shutting down), a pool can be cut off
half-way and leave its workers idle and orphaned. The job runner therefore builds in a child
process started in a session of its own (``python -m pickstop.runtime.build_process``): every
process of the build (the child, its pools' workers, their resource tracker) is in that
process group, and :meth:`BuildProcess.stop` ends them all at once (SIGTERM, then SIGKILL).
The child also ends its group when its stdin closes, so a build never outlives the service
that started it, however that ends.

Protocol: the parent writes one JSON line (the robot config, the folder its paths start from,
the build parameters, the data folder) and keeps stdin open; the child answers JSON lines:
``{"database": id}`` once the build is registered, ``{"progress": [done, total]}`` as chunks
finish, then ``{"result": row}`` or ``{"error": base64 of a pickled error}``.
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from pickstop.errors import PickStopError, dump_error, load_error

POLL = 0.1  # [s] between looks for a stop while waiting for the child's next line
GRACE = 5.0  # [s] a stopped build has to unwind before it is killed


class BuildProcess:
    """One build in a child process group (see the module docstring)."""

    def __init__(self, config: Any, root: Path, params: Any, data_dir: Path) -> None:
        """config: the robot's :class:`~pickstop.robot.config.RobotConfig`, its paths from
        ``root``; params: :class:`~pickstop.reach.build.BuildParams`."""
        job = {
            "config": config.model_dump(mode="json"),
            "root": str(root),
            "params": dataclasses.asdict(params),
            "data_dir": str(data_dir),
        }
        env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "pickstop.runtime.build_process"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # its own process group: stop() ends every process in it
            env=env,
        )
        self._lock = threading.Lock()
        self._stopped = False
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps(job).encode() + b"\n")
        self.proc.stdin.flush()

    def messages(self) -> Iterator[dict[str, Any]]:
        """The child's messages as they come, until it ends; waits in short polls, so that a
        :class:`~pickstop.api.work.Cancelled` raised in this thread arrives at once."""
        out = self.proc.stdout
        assert out is not None
        buf = b""
        while True:
            ready, _, _ = select.select([out], [], [], POLL)
            if not ready:
                continue
            chunk = os.read(out.fileno(), 65536)
            if not chunk:
                return
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                yield json.loads(line)

    def stop(self) -> None:
        """End every process of the build (idempotent): SIGTERM to the group, SIGKILL to
        whatever is left after :data:`GRACE` seconds; the child is reaped last, so that the
        group's id cannot pass to another group meanwhile."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            if self.proc.stdin is not None:
                with contextlib.suppress(OSError):
                    self.proc.stdin.close()
            _signal_group(self.proc.pid, signal.SIGTERM)
            end = time.monotonic() + GRACE
            while time.monotonic() < end and not _exited(self.proc.pid):
                time.sleep(0.05)
            _signal_group(self.proc.pid, signal.SIGKILL)  # its workers, if they linger
            self.proc.wait()
            if self.proc.stdout is not None:
                self.proc.stdout.close()

    @property
    def pid(self) -> int:
        return self.proc.pid


def error_of(message: dict[str, Any]) -> BaseException:
    """The error a child sent (``{"error": ...}``)."""
    return load_error(base64.b64decode(message["error"]), PickStopError, "the build failed")


def _exited(pid: int) -> bool:
    """Whether the child ``pid`` has ended, without reaping it."""
    flags = os.WEXITED | os.WNOWAIT | os.WNOHANG
    try:
        return os.waitid(os.P_PID, pid, flags) is not None
    except ChildProcessError:
        return True


def _signal_group(pgid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


# -- the child side --------------------------------------------------------------------------
def _send(out: IO[str], msg: dict[str, Any]) -> None:
    out.write(json.dumps(msg) + "\n")
    out.flush()


def _end_group_at_eof() -> None:
    """Wait for stdin to close (the parent stopped us, or died), then end this group."""
    with contextlib.suppress(OSError):
        while sys.stdin.buffer.read(65536):
            pass
    os.killpg(0, signal.SIGTERM)


def main() -> None:
    """The child: build what the parent's first line says, reporting on stdout."""
    out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # anything printed goes to stderr, never into the protocol
    # Stopped: end at once. The catalog finds the build's process gone and calls it
    # interrupted; its pool's workers get the same signal.
    signal.signal(signal.SIGTERM, lambda *_: os._exit(143))
    job = json.loads(sys.stdin.buffer.readline())
    threading.Thread(target=_end_group_at_eof, daemon=True).start()
    os.nice(10)  # interactive requests come first
    try:
        _send(out, {"result": _build(job, out)})
    except Exception as e:
        _send(out, {"error": base64.b64encode(dump_error(e)).decode()})
    os._exit(0)  # the pools are shut down; nothing else (the stdin watcher) is waited for


def _build(job: dict[str, Any], out: IO[str]) -> dict[str, Any]:
    from pickstop.reach.build import BuildParams, database_id
    from pickstop.robot.config import RobotConfig
    from pickstop.robot.floor import floor_identity
    from pickstop.robot.model import load_robot
    from pickstop.store.reach_build import build

    robot = load_robot(RobotConfig.model_validate(job["config"]), Path(job["root"]))
    params = BuildParams(**job["params"])
    params.validate()
    _send(out, {"database": database_id(robot.robot_hash, params, floor_identity(robot))})
    row = build(robot, params, Path(job["data_dir"]), workers=2, nice=10,
                progress=lambda done, total: _send(out, {"progress": [done, total]}))  # fmt: skip
    return {"database": row["id"], "robot": robot.name, "samples": row["samples"]}


if __name__ == "__main__":
    main()
