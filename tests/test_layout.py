"""The package layout: no import cycle between csim's packages and top-level modules,
counting the imports inside functions (a deferred import only hides a cycle)."""
from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

CSIM = Path(__file__).resolve().parents[1] / "csim"


def _unit(module: str) -> str | None:
    """The layout unit of a module: its top-level package or module under csim (None outside csim)."""
    parts = module.split(".")
    if parts[0] != "csim" or len(parts) == 1:
        return None
    return parts[1]


def import_graph(root: Path = CSIM) -> dict[str, dict[str, list[str]]]:
    """unit -> imported unit -> the imports that make the edge (``module:line``), every import
    statement of every file of the package at ``root`` counted, at the top or inside a function."""
    edges: dict[str, dict[str, list[str]]] = defaultdict(lambda: defaultdict(list))
    for path in root.rglob("*.py"):
        parts = path.relative_to(root.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        package = ".".join(parts[:-1])
        source = _unit(module)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from the package, one level up per extra dot
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join([*up, *filter(None, [base])])
                targets = [f"{base}.{alias.name}" for alias in node.names] if base == "csim" else [base]
            else:
                continue
            for target in targets:
                unit = _unit(target)
                if source and unit and unit != source:
                    edges[source][unit].append(f"{module}:{node.lineno}")
    return edges


def cycles(edges) -> list[list[str]]:
    """The strongly connected components of more than one unit (Tarjan's algorithm)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(set(edges) | {w for targets in edges.values() for w in targets}):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle_between_packages():
    edges = import_graph()
    found = cycles(edges)
    detail = [f"{a} -> {b}: {edges[a][b][0]}" for comp in found for a in comp for b in edges[a] if b in comp]
    assert not found, f"import cycles {found}:\n" + "\n".join(detail)


def test_the_check_finds_a_cycle_hidden_in_a_function(tmp_path):
    """A package whose ``physics`` imports ``solver`` inside a function, and whose ``solver``
    imports ``physics`` relatively at the top: the graph has both edges, and the cycle is found."""
    package = tmp_path / "csim"
    for unit in ("physics", "solver"):
        (package / unit).mkdir(parents=True)
        (package / unit / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "physics" / "status.py").write_text("def message():\n    from csim.solver import failures\n")
    (package / "solver" / "failures.py").write_text("from ..physics import status\n")
    edges = import_graph(package)
    assert "solver" in edges["physics"] and "physics" in edges["solver"], dict(edges)
    assert cycles(edges) == [["physics", "solver"]]


def test_the_core_imports_only_itself_and_the_leaves():
    """csim.physics, the numba-able core both backends run, imports no other csim package."""
    assert not set(import_graph()["physics"]) - {"errors"}, dict(import_graph()["physics"])


#: the longest a function of csim may be, in lines (docstring included): issue 22's rule
MAX_FUNCTION_LINES = 100


def long_functions(root: Path = CSIM, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``file:line name (lines)`` of every function of ``root`` longer than ``limit`` lines."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > limit:
                    found.append(f"{path.relative_to(root.parent)}:{node.lineno} {node.name} ({lines})")
    return found


def test_no_function_is_over_a_hundred_lines():
    assert long_functions() == []


def test_the_length_check_finds_a_long_function(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    (tmp_path / "m.py").write_text(f"def long():\n{body}\n\ndef short():\n    pass\n")
    assert long_functions(tmp_path) == [f"{tmp_path.name}/m.py:1 long ({MAX_FUNCTION_LINES + 1})"]
