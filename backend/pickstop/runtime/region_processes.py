"""Regions computed by several processes at once, each tray at home in one of them.

The planner's process is one of the ``processes``; the others are helpers forked from it,
which live as long as the pool. Forked children share the parent's reachability database (its
pages are copied only if written, and they are only read) and start with its memos. Each tray
(with its yaw) has a **home**: the process that computed its region last computes it again,
so what its memos learned there (grasps, refinements, remembered cell answers across tray
positions: :mod:`pickstop.speedups.region_memo`) serves the next layout. A tray new to the pool goes
to the process with the least to do. Nothing is pickled but the scene going out and the
regions coming back (a few hundred kB, about a millisecond), with the grasps the helper
computed for them (the planner's checks of stops need them too).

A region computed here is the one the planner's process would compute from the same memos:
every cell it calls feasible carries a witness verified for the real geometry there.

A request given up stops in the helpers as in the planner: once the token of the computation
asking (:mod:`pickstop.runtime.cancel`) is cancelled, or the asking thread stops waiting for
any other reason, a flag in shared memory cancels each helper's token, every helper stops at
its next checkpoint (:meth:`~pickstop.regions.kit.RegionKit.checkpoint`), and
:class:`~pickstop.runtime.cancel.Cancelled` is raised once they have. A helper that dies is
replaced on the next call, and its share computed by the planner's process meanwhile.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from pickstop.caching import Cache
from pickstop.errors import dump_error, load_error
from pickstop.regions.cells import TrayRegion
from pickstop.regions.kit import RegionKit
from pickstop.runtime.cancel import Cancelled, Token, current, scope
from pickstop.scene.model import Scene

log = logging.getLogger("pickstop.regions")

Pair = tuple[str, float]  # (tray id, yaw [rad])
Compute = Callable[[Scene, str, float], TrayRegion]
POLL = 0.005  # [s] between looks at the asking thread's token while helpers compute
MAX_HOMES = 4096  # trays (by definition but for where they stand) whose homes are kept
_COMPUTE: Compute | None = None  # how a helper computes a region (set in each helper)


@dataclass
class _Helper:
    process: Any  # multiprocessing.Process
    conn: Connection


class RegionProcesses:
    """``processes`` processes computing regions with ``kit``: the caller's own and
    ``processes - 1`` helpers forked from it, each tray at home in one (see the module);
    ``compute(scene, tray id, yaw)`` computes a region, here and in every helper."""

    def __init__(self, kit: RegionKit, processes: int, compute: Compute) -> None:
        if processes < 1:
            raise ValueError(f"processes must be at least 1, got {processes}")
        self.kit = kit
        self.compute = compute
        self.processes = processes
        # home key -> process (0: this one)
        self.homes: Cache[str, int] = Cache("region_processes.homes", max_items=MAX_HOMES)
        self._ctx = multiprocessing.get_context("fork")
        self._stop = self._ctx.RawValue("b", 0)  # shared: 1 while helpers are to give way
        self._helpers: list[_Helper | None] = [None] * (processes - 1)
        self._rid = 0

    def regions(self, scene: Scene, pairs: list[Pair]) -> list[TrayRegion]:
        """The region of each ``(tray id, yaw)`` of ``scene``, in order: those at home here by
        :attr:`compute`, the others by their helpers (with the same function) meanwhile.

        Raises :class:`~pickstop.runtime.cancel.Cancelled` (after every helper stopped) once
        this thread's token is cancelled."""
        share = self._share(scene, pairs)
        out: dict[Pair, TrayRegion] = {}
        sent: dict[int, int] = {}  # helper index -> request id
        self._stop.value = 0
        for h in range(1, self.processes):
            mine = [p for p, w in zip(pairs, share, strict=True) if w == h]
            if mine and (rid := self._send(h - 1, scene, mine)) is not None:
                sent[h - 1] = rid
            elif mine:
                share = [0 if w == h else w for w in share]  # no helper: computed here
        try:
            for p, w in zip(pairs, share, strict=True):
                if w == 0:
                    out[p] = self.compute(scene, *p)
            for h, rid in list(sent.items()):
                kind, payload = self._receive(h, rid)
                del sent[h]  # answered
                if kind == "error":
                    raise load_error(payload)
                if kind == "cancelled":
                    raise Cancelled(current().reason or "cancelled")
                if kind == "ended":  # the helper died: its share is computed here
                    for p, w in zip(pairs, share, strict=True):
                        if w == h + 1:
                            self._home(_home_key(scene, p), 0)
                            out[p] = self.compute(scene, *p)
                    continue
                regions, grasps = payload
                self.kit.learn_grasps(grasps)  # the stops' checks here need them too
                out.update(regions)
        except BaseException:
            self._stop.value = 1
            for h, rid in sent.items():  # those not answered yet
                self._drain(h, rid)
            raise
        return [out[p] for p in pairs]

    def _home(self, key: str, w: int) -> None:
        self.homes.put(key, w)

    def _share(self, scene: Scene, pairs: list[Pair]) -> list[int]:
        """Which process computes each pair: its home, else the one with the least to do
        (then the fewest homes)."""
        load = [0] * self.processes
        homes = [0] * self.processes
        for w in self.homes.values():
            if w < self.processes:
                homes[w] += 1
        keys = [_home_key(scene, p) for p in pairs]
        out: list[int | None] = []
        for key in keys:
            home = self.homes.get(key)
            out.append(home if home is not None and home < self.processes else None)
            if out[-1] is not None:
                load[out[-1]] += 1
                self._home(key, out[-1])  # recently used: kept
        for i, key in enumerate(keys):
            if out[i] is None:
                w = min(range(self.processes), key=lambda k: (load[k], homes[k], k))
                homes[w] += 1
                load[w] += 1
                out[i] = w
                self._home(key, w)
        return [w for w in out if w is not None]

    def _send(self, h: int, scene: Scene, pairs: list[Pair]) -> int | None:
        """Ask helper ``h`` for the regions of ``pairs``: the request's id, or None if no
        helper can be started."""
        self._rid += 1
        for _ in range(2):  # a helper found dead is replaced once
            helper = self._helpers[h] or self._start(h)
            try:
                helper.conn.send((self._rid, scene, pairs))
                return self._rid
            except (OSError, ValueError):
                self._retire(h)
        return None

    def _receive(self, h: int, rid: int) -> tuple[str, Any]:
        """Helper ``h``'s answer to request ``rid``: ``("ok", (regions, grasps))``,
        ``("error", pickled exception)``, ``("cancelled", None)``, or ``("ended", None)`` if
        it died. Raises :class:`~pickstop.runtime.cancel.Cancelled` once this thread's token
        is cancelled (the answer is still to come then)."""
        helper = self._helpers[h]
        assert helper is not None
        token = current()
        while True:
            try:
                if not helper.conn.poll(POLL):
                    token.check()
                    continue
                got_rid, kind, payload = helper.conn.recv()
            except (EOFError, OSError):
                log.warning("a region helper process ended; its trays are computed here")
                self._retire(h)
                return "ended", None
            if got_rid == rid:
                return kind, payload
            # else the answer to a request given up before

    def _drain(self, h: int, rid: int) -> None:
        """Wait for helper ``h`` to answer request ``rid`` (it stops at its next checkpoint),
        so that the next request finds it idle; a helper that does not answer is replaced."""
        helper = self._helpers[h]
        if helper is None:
            return
        try:
            while helper.conn.poll(5.0):
                if helper.conn.recv()[0] == rid:
                    return
        except (EOFError, OSError):
            pass
        self._retire(h)

    def _start(self, h: int) -> _Helper:
        mine, theirs = self._ctx.Pipe()
        proc = self._ctx.Process(
            target=_serve,
            args=(self.kit, self.compute, theirs, mine, self._stop),
            name=f"pickstop-regions-{h + 1}",
            daemon=True,
        )
        proc.start()
        theirs.close()
        helper = self._helpers[h] = _Helper(proc, mine)
        return helper

    def _retire(self, h: int) -> None:
        helper, self._helpers[h] = self._helpers[h], None
        if helper is not None:
            helper.conn.close()
            helper.process.kill()
            helper.process.join(timeout=5)

    @property
    def pids(self) -> list[int | None]:
        """The helpers' process ids (None: not started, or ended)."""
        return [None if h is None else h.process.pid for h in self._helpers]

    def close(self) -> None:
        """Stop the helper processes."""
        for h in range(len(self._helpers)):
            self._retire(h)


def _home_key(scene: Scene, pair: Pair) -> str:
    """What a home is kept by: the tray's definition but for where it stands, its id and the
    yaw (the memos of a tray moved about are one tray's)."""
    tray = scene.tray(pair[0])
    return f"{tray.id}|{pair[1]!r}|{tray.model_dump_json(exclude={'pose': {'x', 'y'}})}"


def _serve(
    kit: RegionKit, compute: Compute, conn: Connection, parents: Connection, stop: Any
) -> None:
    """A helper's life: regions for the planner's requests until its end of the pipe closes."""
    global _COMPUTE
    parents.close()  # so that the planner's end closing reads as the end here
    _COMPUTE = compute
    code = 0
    try:
        while True:
            try:
                rid, scene, pairs = conn.recv()
            except (EOFError, OSError):
                break
            try:
                known = set(kit.grasp_memo)
                with scope(Token(lambda: bool(stop.value), reason="cancelled")):
                    out = [(p, _region(scene, *p)) for p in pairs]
                grasps = {k: g for k, g in kit.grasp_memo.items() if k not in known}
                conn.send((rid, "ok", (out, grasps)))
            except Cancelled:
                conn.send((rid, "cancelled", None))
            except Exception as e:
                conn.send((rid, "error", dump_error(e)))
    except (OSError, ValueError):
        code = 1
    finally:
        os._exit(code)  # nothing of the planner's process (threads, exit handlers) runs here


def _region(scene: Scene, tray_id: str, yaw: float) -> TrayRegion:
    compute = _COMPUTE
    assert compute is not None, "a region helper runs only in a RegionProcesses process"
    return compute(scene, tray_id, yaw)
