"""The house: no import circles, and no import from a lower floor to a higher one.

Every ``import`` and ``from ... import`` in ``bedstruct/`` counts, wherever it
stands (module level, inside a function, under ``TYPE_CHECKING``): an import
hidden in a function body still ties the two modules together.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "bedstruct"

#: Floor of each top-level module or subpackage: a module may import its own subpackage
#: and anything on a lower floor, nothing on its own floor elsewhere or above.
FLOORS = {
    "_version": 0, "errors": 0, "_numba": 0, "_atomic": 0,
    "_json": 1, "core": 1,
    "io": 2, "analysis": 2,
    "dem": 3, "plot": 3,
    "engines": 4,
    "workflows": 5, "report": 5,
    "diagnose": 6,
    "cli": 7,
    "__main__": 8,
}


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: pathlib.Path, name: str, modules: set[str]) -> set[str]:
    is_package = path.name == "__init__.py"
    base = name.split(".") if is_package else name.split(".")[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                stem = ".".join(base[:len(base) - (node.level - 1)] + ([node.module] if node.module else []))
            else:
                stem = node.module or ""
            targets = [f"{stem}.{a.name}" if f"{stem}.{a.name}" in modules else stem
                       for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:  # `import bedstruct.io.formats.read` -> the module
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the bedstruct modules it imports."""
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    modules = set(paths)
    return {m: _imports(p, m, modules) for m, p in paths.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
    return found


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_the_checker_finds_a_circle_and_an_upward_import():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert circles(graph) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []
    assert _room("bedstruct.diagnose.where") == "diagnose" and _room("bedstruct") is None


def test_every_room_has_a_floor():
    rooms = {_room(m) for m in import_graph()} - {None}
    assert rooms <= set(FLOORS), f"give these a floor in FLOORS: {sorted(rooms - set(FLOORS))}"


def test_no_import_circles():
    found = circles(import_graph())
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_no_import_runs_up_a_floor():
    bad = []
    for module, targets in import_graph().items():
        here = _room(module)
        if here is None:  # the package's face imports only the ground floor eagerly
            bad += [f"bedstruct -> {t}" for t in targets if FLOORS.get(_room(t), 99) > 1]
            continue
        for t in targets:
            there = _room(t)
            if there is None:
                bad.append(f"{module} -> bedstruct (import the module, not the package face)")
            elif there != here and FLOORS[there] >= FLOORS[here]:
                bad.append(f"{module} (floor {FLOORS[here]}) -> {t} (floor {FLOORS[there]})")
    assert not bad, "imports from a lower floor to a higher one:\n" + "\n".join(sorted(bad))


@pytest.mark.parametrize("package", sorted(p.parent.name for p in PACKAGE.glob("*/__init__.py")))
def test_public_names_are_a_static_list(package):
    """``__all__`` of each subpackage is a literal list that tools can read without importing."""
    tree = ast.parse((PACKAGE / package / "__init__.py").read_text())
    values = [n.value for n in tree.body if isinstance(n, ast.Assign)
              and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets)]
    assert values, f"bedstruct.{package} has no __all__"
    names = ast.literal_eval(values[-1])
    assert names and all(isinstance(n, str) for n in names)
