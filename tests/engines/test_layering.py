"""Where the external engines sit: on the floor of ``dem`` and ``io``, below the workflows,
with no import circle among the engines' modules or between the workflows and their
external implementations. Read from the source with ``ast`` (imports inside functions
count too)."""

from __future__ import annotations

import ast
from pathlib import Path

import bedstruct

ROOT = Path(bedstruct.__file__).parent


def _imports(path: Path) -> set[str]:
    """Absolute names of the bedstruct modules (or packages) that ``path`` imports."""
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = list(rel.parts)
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            for alias in node.names:   # `from . import x` names a module
                out.add(mod + "." + alias.name if node.module is None else mod)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return {m for m in out if m.startswith("bedstruct")}


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = list(rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _graph(paths) -> dict[str, set[str]]:
    return {_module(p): _imports(p) for p in paths}


def _cycle(graph: dict[str, set[str]]):
    """One import circle among the graph's nodes, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in graph:
                continue
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_engines_import_nothing_above_their_floor():
    above = ("bedstruct.workflows", "bedstruct.report", "bedstruct.diagnose", "bedstruct.cli",
             "bedstruct.plot")
    for mod, imports in _graph(sorted((ROOT / "engines").glob("*.py"))).items():
        bad = sorted(m for m in imports if m.startswith(above))
        assert not bad, f"{mod} imports {bad}"


def test_no_import_circle_among_the_engines_modules():
    graph = _graph(sorted((ROOT / "engines").glob("*.py")))
    graph.pop("bedstruct.engines")   # the package re-exports; its modules do not import it
    assert _cycle(graph) is None, _cycle(graph)


def test_workflows_dispatch_down_to_their_external_implementations():
    names = ("repose", "repose_measure", "spread", "spread_measure", "spread_pile", "external",
             "external_spread", "_common", "calibrate")
    graph = _graph([ROOT / "workflows" / f"{n}.py" for n in names])
    assert _cycle(graph) is None, _cycle(graph)
    for ext in ("bedstruct.workflows.external", "bedstruct.workflows.external_spread"):
        assert not graph[ext] & {"bedstruct.workflows.repose", "bedstruct.workflows.spread"}
    assert "bedstruct.workflows.external" in graph["bedstruct.workflows.repose"]
    assert "bedstruct.workflows.external_spread" in graph["bedstruct.workflows.spread"]


def test_no_deck_writer_left_under_dem():
    assert not (ROOT / "dem" / "backends").exists()


def test_no_engine_branch_in_the_scenario_writers():
    for name in ("_bed.py", "_repose.py", "_spread.py", "_bench.py", "_dialect.py"):
        src = (ROOT / "engines" / name).read_text()
        for engine in ("liggghts", "lammps"):
            assert f'== "{engine}"' not in src and f"== '{engine}'" not in src, (name, engine)
