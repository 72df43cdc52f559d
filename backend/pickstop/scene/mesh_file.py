"""A scene's mesh files checked before anything plans with them.

A mesh file can lie: a binary STL whose header claims 100 triangles in 512 MB, or 199,000 in
none; an ASCII STL of 256 MB on one line. Each is refused here, naming what is wrong, in time
bounded by the file's size (itself bounded by the triangles it may hold); then the file is
loaded as the planner loads it (coal), so that a file that passes is one the planner reads,
with the triangles counted and a size of its own. :class:`MeshFiles` remembers what each file
was found to be by its path, size and modification time.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pickstop.caching import Cache
from pickstop.errors import InputError

BYTES_PER_TRIANGLE = 400  # an ASCII STL facet takes about 250 bytes, an OBJ face far fewer
MAX_LINE = 1 << 16  # [bytes] longest line of a text mesh
CHUNK = 1 << 20  # [bytes] read at a time
MIN_EXTENT = 1e-4  # [m] smallest extent of a scaled mesh along x and y (scene MIN_SIZE)


class MeshFileError(InputError):
    """A mesh file is not what it claims to be, or not one the planner can read."""


@dataclass(frozen=True)
class MeshFacts:
    """What a mesh file holds: its triangles and its extent along x, y, z [m, unscaled]."""

    triangles: int
    extent: tuple[float, float, float]


def claimed_triangles(path: Path) -> int | None:
    """The triangles a binary STL's header claims (None for other files): read first, so
    that a file claiming too many is refused by the limit before anything reads it."""
    if path.suffix.lower() != ".stl":
        return None
    with path.open("rb") as f:
        head = f.read(84)
    if len(head) < 84 or head.lstrip().startswith(b"solid"):
        return None
    return int.from_bytes(head[80:84], "little")


class MeshFiles:
    """:func:`check_mesh`, remembered for the last ``size`` files (by path, size and
    modification time: a changed file is checked again)."""

    def __init__(self, size: int = 256) -> None:
        self._known: Cache[tuple[str, int, int], MeshFacts] = Cache("mesh_files", max_items=size)

    def check(self, path: Path, max_triangles: int, scale: float = 1.0) -> MeshFacts:
        stat = path.stat()
        key = (str(path), stat.st_size, stat.st_mtime_ns)
        facts = self._known.get_or_make(
            key, lambda: inspect_mesh(path, stat.st_size, max_triangles)
        )
        check_extent(facts, scale)
        return facts


def check_mesh(path: Path, max_triangles: int, scale: float = 1.0) -> MeshFacts:
    """The facts of the mesh file ``path`` (scaled by ``scale`` in the scene), or
    :class:`MeshFileError` saying why it is refused: more bytes than ``max_triangles``
    triangles take, a binary STL whose size disagrees with its header, a text mesh with a line
    over :data:`MAX_LINE` bytes or facets without their three vertices, a file the planner's
    loader cannot read, or one flatter than :data:`MIN_EXTENT` along x or y once scaled."""
    facts = inspect_mesh(path, path.stat().st_size, max_triangles)
    check_extent(facts, scale)
    return facts


def check_extent(facts: MeshFacts, scale: float) -> None:
    if min(facts.extent[:2]) * scale < MIN_EXTENT:
        raise MeshFileError(
            f"the mesh is {facts.extent[0] * scale:.3g} x {facts.extent[1] * scale:.3g} m "
            f"across once scaled, flatter than {MIN_EXTENT:g} m"
        )


def inspect_mesh(path: Path, size: int, max_triangles: int) -> MeshFacts:
    """What :func:`check_mesh` finds of a file of ``size`` bytes, its extent aside."""
    limit = max_triangles * BYTES_PER_TRIANGLE + 84
    if size > limit:
        raise MeshFileError(f"the file holds {size} bytes, more than {max_triangles} "
                            f"triangles take (at most {limit} bytes)")  # fmt: skip
    suffix = path.suffix.lower()
    expected = None
    if suffix == ".stl":
        expected = _stl_triangles(path, size)
    elif suffix == ".obj":
        _text_lines(path, {})
    facts = _load(path)
    if expected is not None and facts.triangles != expected:
        raise MeshFileError(f"the file holds {expected} triangles but reads as "
                            f"{facts.triangles}")  # fmt: skip
    return facts


def _stl_triangles(path: Path, size: int) -> int:
    """Triangles of an STL, binary (its size must be 84 + 50 n for the n its header says) or
    ASCII (every facet with three vertices)."""
    claimed = claimed_triangles(path)
    with path.open("rb") as f:
        head = f.read(84)
    if len(head) == 84:
        n = int.from_bytes(head[80:84], "little")
        if size == 84 + 50 * n and n > 0:
            return n  # binary, even if its header begins with "solid"
    if not head.lstrip().startswith(b"solid"):
        have = max(size - 84, 0) / 50
        raise MeshFileError(f"binary STL: its header claims {claimed} triangles, its "
                            f"{size} bytes hold {have:g}")  # fmt: skip
    counts = _text_lines(path, {"facet": b"facet", "vertex": b"vertex", "end": b"endsolid"})
    if not counts["end"]:
        raise MeshFileError("ASCII STL: no 'endsolid' line (the file is cut short)")
    if counts["facet"] == 0 or counts["vertex"] != 3 * counts["facet"]:
        raise MeshFileError(f"ASCII STL: {counts['facet']} facets with {counts['vertex']} "
                            "vertices (three each expected)")  # fmt: skip
    return counts["facet"]


def _text_lines(path: Path, first_words: dict[str, bytes]) -> dict[str, int]:
    """Lines of a text mesh whose first word is each of ``first_words``; refuses a line over
    :data:`MAX_LINE` bytes. Reads the file once, a chunk at a time."""
    patterns = {
        k: re.compile(rb"^[ \t]*" + re.escape(w) + rb"\b", re.M) for k, w in first_words.items()
    }
    counts = dict.fromkeys(first_words, 0)
    rest = b""
    with path.open("rb") as f:
        while chunk := f.read(CHUNK):
            text = rest + chunk
            cut = text.rfind(b"\n") + 1
            text, rest = text[:cut], text[cut:]
            if len(rest) > MAX_LINE:
                raise MeshFileError(f"a line of more than {MAX_LINE} bytes: not a mesh")
            for k, rx in patterns.items():
                counts[k] += len(rx.findall(text))
    if len(rest) > MAX_LINE:
        raise MeshFileError(f"a line of more than {MAX_LINE} bytes: not a mesh")
    for k, rx in patterns.items():
        counts[k] += len(rx.findall(rest))
    return counts


def _load(path: Path) -> MeshFacts:
    """The file loaded as the planner loads it (coal's mesh loader)."""
    import coal

    try:
        mesh = coal.MeshLoader().load(str(path), np.ones(3))
    except Exception as e:  # coal's message names server paths: keep only what went wrong
        lines = [ln.strip() for ln in str(e).splitlines()]
        why = next((lines[i + 1] for i, ln in enumerate(lines[:-1])
                    if "Could not load resource" in ln), "unreadable")  # fmt: skip
        raise MeshFileError(f"not a mesh the planner can read ({why})") from None
    if mesh.num_tris == 0:
        raise MeshFileError("the mesh holds no triangles")
    mesh.computeLocalAABB()
    lo, hi = np.asarray(mesh.aabb_local.min_), np.asarray(mesh.aabb_local.max_)
    extent = tuple(float(v) for v in hi - lo)
    if not all(math.isfinite(v) for v in extent):
        raise MeshFileError("the mesh has vertices that are not finite numbers")
    return MeshFacts(int(mesh.num_tris), extent)  # type: ignore[arg-type]
