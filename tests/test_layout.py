"""The package's layout: no module imports back up (no import cycle), lazy imports included."""

import ast
from pathlib import Path

import rrrobot_gym

PACKAGE = Path(rrrobot_gym.__file__).resolve().parent


def _module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, root: Path, modules: set) -> set:
    """The package's modules that ``path`` imports anywhere in it (module level or inside a
    function), relative imports resolved; ``from package import name`` counts ``package.name``
    when that is a module, else ``package``."""
    name = _module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in modules:  # (a name inside a module: the module)
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph(root: Path = PACKAGE) -> dict:
    """{module: the package's modules it imports}, for every .py file under ``root``."""
    files = {_module_name(p, root): p for p in root.rglob("*.py")}
    return {name: _imports(path, root, set(files)) for name, path in files.items()}


def cycles(graph: dict) -> list:
    """Each import cycle once, as a list of modules (depth-first search over the graph)."""
    found, state = [], {}

    def visit(node, stack):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    return found


def _package_an_import_away(tmp_path, sources: dict) -> Path:
    root = tmp_path / "pkg"
    for name, text in sources.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_package_has_no_import_cycle():
    graph = import_graph()
    assert "rrrobot_gym.simulation" in graph and "rrrobot_gym.compiled" in graph["rrrobot_gym.simulation"]
    assert cycles(graph) == []


def test_the_check_finds_a_lazy_import_back_up(tmp_path):
    # simulation imports compiled at the top; compiled imports simulation inside a function
    root = _package_an_import_away(tmp_path, {
        "__init__.py": "",
        "simulation.py": "from . import compiled\n",
        "compiled.py": "def cache_dir():\n    from . import simulation\n    return simulation\n",
        "sub/__init__.py": "",
        "sub/leaf.py": "from ..compiled import cache_dir\nimport pkg.sub\n",
    })  # fmt: skip
    graph = import_graph(root)
    assert graph["pkg.sub.leaf"] == {"pkg.compiled", "pkg.sub"}
    assert cycles(graph) == [["pkg.compiled", "pkg.simulation", "pkg.compiled"]]
