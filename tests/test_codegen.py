"""Generated model code: plain functions, cached by a hash of the symbolic definition."""
from __future__ import annotations

import ast

from csim.mechanisms import get_mechanism
from csim.model.cache import FUNCTIONS, cache_dir, cached_source, definition_key


def test_generated_source_uses_only_math_and_numpy():
    source = cached_source(get_mechanism("quick_return"))
    tree = ast.parse(source)
    imports = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert imports == {"math", "numpy"}
    defined = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert defined == set(FUNCTIONS)


def test_source_is_cached_under_the_definition_hash():
    mech = get_mechanism("quick_return")
    cached_source(mech)
    path = cache_dir() / f"quick_return-{definition_key(mech)}.py"
    assert path.is_file()
    path.write_text(path.read_text() + "\n# marker\n")
    assert cached_source(mech).endswith("# marker\n")  # read back, not derived again
    path.unlink()


def test_the_key_changes_with_the_definition():
    a = get_mechanism("quick_return")
    b = get_mechanism("quick_return")
    b.constraints = [b.constraints[0], 2 * b.constraints[1]]
    assert definition_key(a) != definition_key(b)
