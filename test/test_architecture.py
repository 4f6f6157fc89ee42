"""The package's imports point down its floors, and run in no circle (issue 15; docs/architecture.md).

Every ``.py`` file of ``ambiegen_ros/`` and ``sim_nodes/`` is read with ``ast`` (nothing is
imported or run). Each ``import``/``from ... import`` anywhere in a file (at the top, inside a
function, under ``if TYPE_CHECKING``) and each ``import_module("literal")`` is resolved to a
project module: ``from pkg import name`` means the module ``pkg.name`` when there is one, else
``pkg`` itself. Names that a package loads by a computed string (the lazy ``__getattr__`` of
``sims``, ``problems``, ``experiment``) are not seen; they stay inside their own package.

The checks, each failure naming the file and line of the import:
* no circle between modules (a strongly connected component of the import graph), shown as a
  path ``a -> b -> a``;
* no import from a lower floor to a higher one (``FLOORS``, ``ONLY``);
* nothing outside ``cli`` imports the command line but the console scripts' launcher
  (``CLI_LAUNCHERS``): a ``__main__`` of a library package (``python -m ambiegen_ros.doctor``) is a
  launcher on the floors, yet it runs the library, so it must not reach into ``cli`` either;
* no ROS library below the ``ros`` floor, and the middleware (rclpy, Cyclone DDS) imported only
  by the transport seam (``SEAM_EXCEPTIONS`` lists the known bypasses, each with its reason).
"""
from __future__ import annotations

import ast
import sys
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ambiegen_ros", "sim_nodes")

# --- the floors: the one table of the architecture ---------------------------------------------------
# A module may import modules of its own unit, and of any unit on a LOWER floor; two units on one
# floor may import each other (the cycle check keeps that from going round). A unit is a top-level
# module or subpackage of ambiegen_ros (``ambiegen_ros.sims``), or ``sim_nodes``. Every
# ``__main__`` module is a launcher, whatever package it sits in (``python -m ...``).
FLOORS: dict[str, int] = {
    # -1: the package's own __init__: the version string, importing nothing of the project
    "ambiegen_ros": -1,
    # 0: the search engine and its vocabulary (attributes, scenarios, problems' interface, runs), and
    #    deps, the standard-library-only dependency check that setup.py and the launcher read
    "ambiegen_ros.core": 0,
    "ambiegen_ros.deps": 0,
    # 1: the case studies' surrogates and their full-model simulators and oracles; ROS-free
    "ambiegen_ros.problems": 1,
    "ambiegen_ros.sims": 1,
    # 2: the ROS seam: messages, topics, QoS, the transport with its two backends, MCAP logs
    "ambiegen_ros.ros": 2,
    # 3: the library that uses it: nodes, sim nodes, campaigns, experiments, run configs,
    #    launch files' logic, plots (viz reads problems/sims only, but commands and reports use it)
    #    and the doctor (it probes the transport)
    "ambiegen_ros.nodes": 3,
    "sim_nodes": 3,
    "ambiegen_ros.campaign": 3,
    "ambiegen_ros.trials": 3,
    "ambiegen_ros.experiment": 3,
    "ambiegen_ros.run_config": 3,
    "ambiegen_ros.launch_logic": 3,
    "ambiegen_ros.nav2_params": 3,
    "ambiegen_ros.viz": 3,
    "ambiegen_ros.doctor": 3,
    # 4: the command line, the only place that knows argparse
    "ambiegen_ros.cli": 4,
    # 5: launchers: the console scripts' entry (it imports what it launches by name) and __main__s
    "ambiegen_ros.entry": 5,
    "__main__": 5,
}
# Units that may import only these units, whatever lies below them.
ONLY: dict[str, set[str]] = {
    "ambiegen_ros": set(),
    "ambiegen_ros.core": {"ambiegen_ros"},  # and core itself: its version stamp in run records
    "ambiegen_ros.deps": set(),
}

# The only modules outside ``cli`` that import it (module -> why); an entry no longer used fails too.
CLI = "ambiegen_ros.cli"
CLI_LAUNCHERS = {
    "ambiegen_ros.entry": "the console scripts' launcher: `ambiegen` runs ambiegen_ros.cli (and its doctor first)",
}

# Libraries of the ROS world: none below floor 2 (``ros``), so floors 0-1 run without ROS.
ROS_LIBRARIES = ("rclpy", "rosidl_runtime_py", "cyclonedds", "rosbags", "mcap", "launch", "launch_ros",
                 "ament_index_python", "nav2_msgs", "geometry_msgs", "nav_msgs", "sensor_msgs", "std_msgs",
                 "tf2_msgs", "builtin_interfaces", "ambiegen_msgs")
# The middleware itself: only the transport seam (``ros/transport/``) imports it.
MIDDLEWARE = ("rclpy", "rosidl_runtime_py", "cyclonedds")
SEAM = "ambiegen_ros.ros.transport"
# (module, imported name) -> why it may bypass the seam; an entry that no longer occurs fails too.
SEAM_EXCEPTIONS: dict[tuple[str, str], str] = {}


@lru_cache(maxsize=None)
def _modules() -> dict[str, tuple[Path, bool]]:
    """Module name -> (file, is a package); a module file shadowed by a package of its name (the
    package wins in Python's import system) is left out."""
    out: dict[str, tuple[Path, bool]] = {}
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            if is_pkg:
                parts = parts[:-1]
            elif (path.with_suffix("") / "__init__.py").exists():
                continue
            out[".".join(parts)] = (path, is_pkg)
    return out


def unit_of(module: str) -> str:
    parts = module.split(".")
    if parts[-1] == "__main__":
        return "__main__"
    if parts[0] == "ambiegen_ros" and len(parts) > 1:
        return ".".join(parts[:2])
    return parts[0]


def _resolve(name: str, modules: dict) -> str | None:
    """The longest project module that ``name`` names or lies in (None: not the project's)."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def _literal(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


@lru_cache(maxsize=None)
def all_imports() -> dict[str, list[tuple[str, int]]]:
    """Module -> [(absolute name it imports, line)], project or not, from the source alone."""
    modules = _modules()
    out: dict[str, list[tuple[str, int]]] = {}
    for name, (path, is_pkg) in modules.items():
        package = name if is_pkg else name.rpartition(".")[0]
        found: list[tuple[str, int]] = []

        def relative(level: int, module: str | None) -> str:
            base = package.split(".")
            base = base[:len(base) - (level - 1)] if level > 1 else base
            return ".".join(base + ([module] if module else []))

        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = relative(node.level, node.module) if node.level else (node.module or "")
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            elif (isinstance(node, ast.Call) and node.args and _literal(node.args[0])
                  and (getattr(node.func, "id", None) == "import_module"
                       or getattr(node.func, "attr", None) == "import_module")):
                target = _literal(node.args[0])
                if target.startswith("."):  # import_module(".x", __name__): relative to this package
                    level = len(target) - len(target.lstrip("."))
                    target = relative(level, target.lstrip(".") or None)
                targets = [target]
            found.extend((target, node.lineno) for target in targets)
        out[name] = sorted(set(found), key=lambda item: (item[1], item[0]))
    return out


@lru_cache(maxsize=None)
def import_graph() -> dict[str, list[tuple[str, int]]]:
    """Module -> [(imported project module, line)]."""
    modules = _modules()
    graph: dict[str, list[tuple[str, int]]] = {}
    for name, found in all_imports().items():
        edges = []
        for target, line in found:
            resolved = _resolve(target, modules)
            if resolved is not None and resolved != name and (resolved, line) not in edges:
                edges.append((resolved, line))
        graph[name] = edges
    return graph


def _where(module: str, line: int) -> str:
    path, _ = _modules()[module]
    return f"{path.relative_to(ROOT)}:{line}"


def import_cycles() -> list[tuple[list[str], list[str]]]:
    """(a shortest circle, all its component's modules) per strongly connected component of more
    than one module (Tarjan)."""
    graph = {m: sorted({t for t, _ in edges}) for m, edges in import_graph().items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(root: str) -> None:  # iterative: deep import chains must not hit the recursion limit
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(graph[child])))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    components.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    cycles = []
    for component in components:  # the shortest way back to its first module (breadth first)
        members, start = set(component), component[0]
        previous: dict[str, str] = {}
        frontier = [start]
        while frontier and start not in previous:
            nxt = []
            for node in frontier:
                for child in graph[node]:
                    if child in members and child not in previous:
                        previous[child] = node
                        nxt.append(child)
            frontier = nxt
        path = [start]
        while len(path) == 1 or path[-1] != start:
            path.append(previous[path[-1]])
        cycles.append((path[::-1], component))
    return cycles


def _describe_cycle(cycle: list[str], component: list[str]) -> str:
    graph = import_graph()
    steps = []
    for a, b in zip(cycle, cycle[1:]):
        line = next(line for target, line in graph[a] if target == b)
        steps.append(f"  {a} -> {b}   ({_where(a, line)})")
    others = sorted(set(component) - set(cycle))
    return ("import circle " + " -> ".join(cycle) + ":\n" + "\n".join(steps)
            + (f"\n  (the same knot also holds {', '.join(others)})" if others else ""))


def layer_violations() -> list[str]:
    """Every import that goes up the floors (or outside a unit's ONLY list), as one line each."""
    out = []
    for module, edges in sorted(import_graph().items()):
        src = unit_of(module)
        for target, line in edges:
            dst = unit_of(target)
            if dst == src:
                continue
            if src in ONLY and dst not in ONLY[src]:
                out.append(f"{_where(module, line)}: {module} imports {target}: {src} may import only itself"
                           + (f" and {', '.join(sorted(ONLY[src]))}" if ONLY[src] else ""))
            elif FLOORS[dst] > FLOORS[src]:
                out.append(f"{_where(module, line)}: {module} imports {target}: {src} (floor {FLOORS[src]}) "
                           f"imports upwards into {dst} (floor {FLOORS[dst]})")
    return out


# --- the tests -----------------------------------------------------------------------------------
def test_every_unit_has_a_floor():
    """A new top-level module or subpackage needs a line in FLOORS (and one in docs/architecture.md)."""
    missing = sorted({unit_of(m) for m in import_graph()} - set(FLOORS))
    assert not missing, f"no floor for {missing}: add them to FLOORS in {Path(__file__).name}"


def test_no_import_cycles():
    cycles = import_cycles()
    assert not cycles, "\n".join(_describe_cycle(*c) for c in cycles)


def test_imports_point_down_the_floors():
    violations = layer_violations()
    assert not violations, "upward imports (see FLOORS in test/test_architecture.py):\n" + "\n".join(violations)



def cli_import_violations() -> tuple[list[str], set[str]]:
    """Imports of ``ambiegen_ros.cli`` from outside it, but by ``CLI_LAUNCHERS``; and the launchers
    that did import it."""
    out, used = [], set()
    for module, edges in sorted(import_graph().items()):
        if unit_of(module) == CLI or module == CLI or module.startswith(CLI + "."):
            continue
        for target, line in edges:
            if target == CLI or target.startswith(CLI + "."):
                if module in CLI_LAUNCHERS:
                    used.add(module)
                else:
                    out.append(f"{_where(module, line)}: {module} imports {target}: only the launcher "
                               f"({', '.join(sorted(CLI_LAUNCHERS))}) imports the command line; the library "
                               "owns the code and cli imports it")
    return out, used


def assert_clean(found: tuple[list[str], set], allowed, name: str) -> None:
    """No violation, and every allowed exception still in use (a stale one is removed)."""
    violations, used = found
    assert not violations, "\n".join(violations)
    stale = sorted(set(allowed) - used)
    assert not stale, f"{name} no longer needed, remove them: {stale}"


def test_only_the_launcher_imports_the_command_line():
    assert_clean(cli_import_violations(), CLI_LAUNCHERS, "CLI_LAUNCHERS (they no longer import ambiegen_ros.cli)")


def ros_library_violations() -> tuple[list[str], set[tuple[str, str]]]:
    """Imports of ROS libraries below floor 2, and of the middleware outside the seam; and the
    ``SEAM_EXCEPTIONS`` that were used."""
    modules, out, used = _modules(), [], set()
    for module, found in sorted(all_imports().items()):
        floor = FLOORS.get(unit_of(module), 0)
        for target, line in found:
            top = target.split(".")[0]
            if _resolve(target, modules) is not None or top not in ROS_LIBRARIES:
                continue
            if floor < FLOORS["ambiegen_ros.ros"]:
                out.append(f"{_where(module, line)}: {module} imports {target}: floor {floor} runs without ROS")
            elif top in MIDDLEWARE and not (module == SEAM or module.startswith(SEAM + ".")):
                if (module, target) in SEAM_EXCEPTIONS:
                    used.add((module, target))
                else:
                    out.append(f"{_where(module, line)}: {module} imports {target}: only {SEAM} imports the "
                               "middleware (use ros.transport)")
    return out, used


def test_ros_libraries_stay_on_the_ros_floors_and_the_middleware_behind_the_seam():
    assert_clean(ros_library_violations(), SEAM_EXCEPTIONS, "SEAM_EXCEPTIONS")


def test_the_checks_see_relative_lazy_and_upward_imports(tmp_path, monkeypatch):
    """The walker itself, on a made-up tree: a relative import inside a function, an
    ``import_module`` literal and a ``from pkg import submodule`` are resolved; the circle, the
    upward arrow and ROS below its floor are reported with file and line."""
    pkg = tmp_path / "ambiegen_ros"
    for sub in ("core", "sims", "cli", "doctor"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (tmp_path / "sim_nodes").mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "core" / "a.py").write_text("def f():\n    from ..sims import b\n")
    (pkg / "sims" / "b.py").write_text("from importlib import import_module\nimport_module('ambiegen_ros.core.a')\n"
                                       "import rclpy.node\n")
    (pkg / "cli" / "c.py").write_text("from ambiegen_ros.core import a\n")
    (pkg / "doctor" / "__main__.py").write_text("from ..cli.c import a\n")  # a library's launcher into cli
    (pkg / "doctor" / "report.py").write_text("def f():\n    import ambiegen_ros.cli\n")  # the library into cli
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    for cached in (_modules, all_imports, import_graph):
        cached.cache_clear()
    try:
        graph = import_graph()
        assert graph["ambiegen_ros.core.a"] == [("ambiegen_ros.sims.b", 2)]
        assert graph["ambiegen_ros.sims.b"] == [("ambiegen_ros.core.a", 2)]
        assert graph["ambiegen_ros.cli.c"] == [("ambiegen_ros.core.a", 1)]
        cycles = import_cycles()
        assert cycles == [(["ambiegen_ros.core.a", "ambiegen_ros.sims.b", "ambiegen_ros.core.a"],
                           ["ambiegen_ros.core.a", "ambiegen_ros.sims.b"])]
        assert "(ambiegen_ros/core/a.py:2)" in _describe_cycle(*cycles[0])
        assert layer_violations() == [
            "ambiegen_ros/core/a.py:2: ambiegen_ros.core.a imports ambiegen_ros.sims.b: ambiegen_ros.core may "
            "import only itself and ambiegen_ros",
            "ambiegen_ros/doctor/report.py:2: ambiegen_ros.doctor.report imports ambiegen_ros.cli: ambiegen_ros.doctor "
            "(floor 3) imports upwards into ambiegen_ros.cli (floor 4)"]  # the floors miss the __main__ one
        assert ros_library_violations()[0] == [
            "ambiegen_ros/sims/b.py:3: ambiegen_ros.sims.b imports rclpy.node: floor 1 runs without ROS"]
        cli_lines, _ = cli_import_violations()
        assert [line.split(": only")[0] for line in cli_lines] == [
            "ambiegen_ros/doctor/__main__.py:1: ambiegen_ros.doctor.__main__ imports ambiegen_ros.cli.c",
            "ambiegen_ros/doctor/report.py:2: ambiegen_ros.doctor.report imports ambiegen_ros.cli"]
    finally:
        for cached in (_modules, all_imports, import_graph):
            cached.cache_clear()
