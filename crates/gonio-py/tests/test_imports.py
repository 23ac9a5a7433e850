"""The package's modules import each other without a loop, counting the imports made
inside functions (which only hide a loop from Python's import machinery): each
module can then be read, and changed, knowing only those below it."""

from __future__ import annotations

import ast
import pathlib

SOURCE = pathlib.Path(__file__).resolve().parent.parent / "python" / "gonio"


def module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(SOURCE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: pathlib.Path, known: set[str]) -> set[str]:
    """The package's modules that `path` imports, anywhere in it."""
    found = set()
    package = module_name(path) if path.name == "__init__.py" else module_name(path.parent)
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        found |= {n for n in names if n in known}
    return found


def graph() -> dict[str, set[str]]:
    files = {module_name(p): p for p in SOURCE.rglob("*.py")}
    known = set(files)
    g = {}
    for name, path in files.items():
        # A package's own `__init__` re-exports its modules; a module importing its
        # package is not a loop through the package's modules.
        g[name] = {m for m in imports(path, known) if m != name and not name.startswith(m + ".")}
    return g


def find_loop(g: dict[str, set[str]]) -> list[str] | None:
    """A loop in `g` (modules other than a package's `__init__` re-exports)."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(g.get(n, ())):
            if state.get(m) == 1:
                return [*stack[stack.index(m) :], m]
            if m not in state and (loop := visit(m)):
                return loop
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(g):
        if n not in state and (loop := visit(n)):
            return loop
    return None


def test_the_loop_finder_finds_a_loop():
    assert find_loop({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_loop({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_no_module_of_the_package_imports_in_a_loop():
    # What the package's `__init__` imports is its public face, not a dependency.
    g = {n: d - {"gonio"} for n, d in graph().items() if n != "gonio"}
    assert "gonio._frame" in g and "gonio._run" in g, sorted(g)
    assert find_loop(g) is None, f"import loop: {' -> '.join(find_loop(g) or [])}"
