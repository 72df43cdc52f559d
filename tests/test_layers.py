"""The layers are one-way: the core plans without the service, the planner UI is only a client.

- Importing the core (robot, reach, scene, regions and their speed-ups, sequence, the planner
  pool) loads no web framework, UI or SQLite: it runs in a batch job, a Dask worker or a
  notebook as it is.
- The planner UI (``pickstop_ui``) imports nothing of the backend but the shared plan schema
  (``pickstop.sequence.plan_model``), the frames module and the scene format's pure parts
  (its defaults and the tray body's boxes, so a wall is drawn where it is checked); robot
  geometry and everything else come over the REST API.
- The backend never imports the UI, except where the programs are wired together: the
  commands that run the planner (``pickstop ui``, ``pickstop demo``) and the stack that starts
  the API and the planner side by side.
- No two modules import each other, directly or round a longer cycle (imports inside
  functions and under ``TYPE_CHECKING`` count: a cycle is a cycle however it is hidden).
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
PACKAGES = {
    "pickstop": ROOT / "backend" / "pickstop",
    "pickstop_ui": ROOT / "frontend" / "pickstop_ui",
}
CORE = [
    "pickstop.robot",
    "pickstop.reach",
    "pickstop.scene",
    "pickstop.regions",
    "pickstop.speedups",
    "pickstop.sequence",
    "pickstop.layout",
    "pickstop.report",
    "pickstop.pool",
]
FORBIDDEN_IN_CORE = ("fastapi", "starlette", "uvicorn", "viser", "sqlite3", "sqlite_utils")
UI_MAY_IMPORT = (
    "pickstop.sequence.plan_model",
    "pickstop.frames",
    "pickstop.scene.defaults",
    "pickstop.scene.tray_body",
)
WIRING = ("pickstop.cli.demo", "pickstop.cli.service", "pickstop.stack")


def _modules() -> dict[str, Path]:
    out = {}
    for top, root in PACKAGES.items():
        for f in root.rglob("*.py"):
            parts = [top, *f.relative_to(root).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = f
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str) -> set[str]:
    """The project modules ``module`` imports anywhere in its text (not its parent packages)."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for n in names:
            target = _resolve(n)
            if target and target != module and not module.startswith(target + "."):
                found.add(target)
    return found


GRAPH = {m: _imports(m) for m in MODULES}


def _cycles() -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(GRAPH):
        if root in index:
            continue
        work = [(root, iter(sorted(GRAPH[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(GRAPH[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_no_import_cycles():
    assert _cycles() == []


def test_the_cycle_finder_finds_cycles(monkeypatch):
    monkeypatch.setitem(GRAPH, "pickstop.sequence.plan_model", {"pickstop.speedups.stop_planner"})
    pair = {"pickstop.speedups.stop_planner", "pickstop.sequence.plan_model"}
    assert any(pair <= set(cycle) for cycle in _cycles())


@pytest.mark.parametrize("package", CORE)
def test_the_core_loads_no_service_ui_or_sqlite(package):
    code = (
        "import importlib, pkgutil, sys\n"
        f"pkg = importlib.import_module({package!r})\n"
        "for m in pkgutil.walk_packages(getattr(pkg, '__path__', []), pkg.__name__ + '.'):\n"
        "    importlib.import_module(m.name)\n"
        f"print(' '.join(sorted(set(sys.modules) & set({FORBIDDEN_IN_CORE!r}))))\n"
    )
    env_path = f"{ROOT / 'backend'}"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True,
        env={"PYTHONPATH": env_path, "PATH": "/usr/bin:/bin"},
    )  # fmt: skip
    assert out.stdout.split() == [], f"importing {package} loads {out.stdout.strip()}"


def test_the_ui_imports_only_the_plan_schema_of_the_backend():
    for m, targets in GRAPH.items():
        if m.startswith("pickstop_ui"):
            backend = {t for t in targets if t.startswith("pickstop.")}
            parents = {"pickstop", "pickstop.sequence", "pickstop.scene"}
            assert backend <= set(UI_MAY_IMPORT) | parents, (m, backend)


def _ui_importers() -> set[str]:
    """The backend modules that import the UI."""
    return {
        m
        for m, targets in GRAPH.items()
        if m.startswith("pickstop.") and any(t.startswith("pickstop_ui") for t in targets)
    }


def test_the_backend_imports_the_ui_only_where_the_programs_are_wired():
    importers = _ui_importers()
    assert importers <= set(WIRING), f"import the UI: {sorted(importers - set(WIRING))}"
    assert set(WIRING) <= importers, f"need not import it: {sorted(set(WIRING) - importers)}"


@pytest.mark.parametrize(
    "module", ["pickstop.speedups.region_planner", "pickstop.cli", "pickstop.cli.plan"]
)
def test_the_ui_guard_finds_a_stray_import(monkeypatch, module):
    """The core, the command line's package and its other modules may not import the UI."""
    monkeypatch.setitem(GRAPH, module, GRAPH[module] | {"pickstop_ui.app"})
    with pytest.raises(AssertionError, match=re.escape(f"import the UI: ['{module}']")):
        test_the_backend_imports_the_ui_only_where_the_programs_are_wired()


HEAVY = ("pydantic", "coal", "pinocchio", "sqlite3", "shapely", "numpy")


SHARED = [m for m in UI_MAY_IMPORT if m != "pickstop.sequence.plan_model"]


@pytest.mark.parametrize("module", SHARED)
def test_what_the_ui_shares_with_the_core_is_pure(module):
    """The frames and the scene format's pure parts load nothing heavy (numpy aside for the
    frames), so the UI takes them without the backend's models."""
    code = (
        f"import sys, {module}\n"
        f"print(' '.join(sorted(m for m in set(sys.modules) & set({HEAVY!r}))))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True,
        env={"PYTHONPATH": f"{ROOT / 'backend'}", "PATH": "/usr/bin:/bin"},
    )  # fmt: skip
    allowed = {"numpy"} if module == "pickstop.frames" else set()
    assert set(out.stdout.split()) <= allowed, f"importing {module} loads {out.stdout.strip()}"


# The algorithm from scratch (docs/architecture.md section 6) and the modules it must not
# reach: the cache primitive, the speed-ups' planners and caches across requests, processes
# and the service.
PURE = [
    "pickstop.sequence.pure",
    "pickstop.regions.pure",
    "pickstop.regions.pipeline",
    "pickstop.regions.solve",
    "pickstop.regions.recall",
    "pickstop.sequence.request",
]
NOT_FROM_SCRATCH = (
    "pickstop.caching",
    "pickstop.api",
    "pickstop.runtime",
    "pickstop.store.records",
    "pickstop.store.catalog",
    "pickstop.pool",
    "pickstop.distributed",
    "pickstop.stack",
    "pickstop.cli",
    "pickstop.speedups",
    "pickstop.layout",
)
#: The core modules that start the runtime's worker processes.
RUNTIME_USERS = ("pickstop.speedups.region_planner",)
#: What the runtime lends the core: the cancellation token, which imports nothing else.
RUNTIME_IN_CORE = ("pickstop.runtime.cancel",)


def _reach(module: str) -> set[str]:
    seen: set[str] = set()
    todo = [module]
    while todo:
        for m in GRAPH.get(todo.pop(), ()):
            if m not in seen:
                seen.add(m)
                todo.append(m)
    return seen


def _under(module: str, prefixes: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


@pytest.mark.parametrize("module", PURE)
def test_the_algorithm_from_scratch_reaches_no_planner_process_or_service(module):
    reached = {m for m in _reach(module) if _under(m, NOT_FROM_SCRATCH)}
    assert reached <= set(RUNTIME_IN_CORE), f"{module} reaches {sorted(reached)}"


def test_the_algorithms_packages_keep_nothing_themselves():
    """No module of regions/ or sequence/ makes a cache: what their helpers keep between
    calls is asked of a ``Keep`` the speed-ups hand in (``regions/keep.py``)."""
    makers = sorted(m for m, targets in GRAPH.items()
                    if _under(m, ("pickstop.regions", "pickstop.sequence"))
                    and "pickstop.caching" in targets)  # fmt: skip
    assert makers == []


def test_the_core_takes_only_the_token_from_the_runtime():
    for m, targets in GRAPH.items():
        if _under(m, tuple(CORE)) and m not in ("pickstop.pool", *RUNTIME_USERS):
            runtime = {t for t in targets if _under(t, ("pickstop.runtime",))}
            assert runtime <= set(RUNTIME_IN_CORE), (m, runtime)
    assert GRAPH["pickstop.runtime.cancel"] == set()


def test_the_reach_finder_finds_what_it_should(monkeypatch):
    monkeypatch.setitem(GRAPH, "pickstop.sequence.steps", {"pickstop.speedups.stop_planner"})
    assert "pickstop.speedups.stop_planner" in _reach("pickstop.sequence.request")


#: The packages the speed-ups wrap: none of their modules imports a speed-up.
BENEATH_SPEEDUPS = ("pickstop.robot", "pickstop.reach", "pickstop.scene", "pickstop.regions",
                    "pickstop.sequence")  # fmt: skip


def _imports_of_speedups_beneath() -> list[tuple[str, str]]:
    return [
        (m, t)
        for m, targets in GRAPH.items()
        if _under(m, BENEATH_SPEEDUPS)
        for t in targets
        if _under(t, ("pickstop.speedups",))
    ]


def test_the_pipelines_import_nothing_of_the_speedups():
    assert _imports_of_speedups_beneath() == []


def test_the_speedups_guard_finds_a_stray_import(monkeypatch):
    monkeypatch.setitem(GRAPH, "pickstop.sequence.mix", {"pickstop.speedups.stop_planner"})
    assert _imports_of_speedups_beneath() == [
        ("pickstop.sequence.mix", "pickstop.speedups.stop_planner")
    ]
