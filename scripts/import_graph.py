"""The package's import graph: circles between modules, and private names imported across modules.

Reads every ``.py`` file under the package folder (default: ``motion_env``) as text; nothing is
imported or run. An import names the module it loads: ``from motion_env.a.b import x`` is an edge
to ``motion_env.a.b`` (to ``motion_env.a.b.x`` when that is a module), relative imports resolved
the same way. Imports inside ``if TYPE_CHECKING:`` are not edges (they never run).

- circles at import time: the strongly connected groups of the graph of module-level imports
  (what Python runs when a module is first imported);
- circles counting the imports inside functions too (``--all``): the modules that depend on each
  other at all, however late the import;
- private imports: ``from motion_env.x import _name`` in another module than ``motion_env.x``
  (``_name`` not a module of its own package), the name's module's business only.

    python scripts/import_graph.py                 # circles at import time, private imports
    python scripts/import_graph.py --all           # circles through function-level imports too
    python scripts/import_graph.py --packages      # also the subpackages' edges and circles

Exits 1 when it finds a circle (of the kinds asked for) or a private import, else 0.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class Module:
    """What one file imports: module-level edges, function-level edges, private names."""

    name: str
    path: Path
    top: set[str] = field(default_factory=set)
    late: set[str] = field(default_factory=set)
    private: list[tuple[int, str, str]] = field(default_factory=list)  # (line, module, name)


def module_names(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under the package folder `root`."""
    names = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(body: list[ast.stmt], in_function: bool) -> list[tuple[ast.stmt, bool]]:
    """Every import statement under `body` with whether it runs only inside a function."""
    found: list[tuple[ast.stmt, bool]] = []
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append((node, in_function))
        elif isinstance(node, ast.If) and _is_type_checking(node):
            found += _imports(node.orelse, in_function)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found += _imports(node.body, True)
        else:
            children = [c for c in ast.iter_child_nodes(node) if isinstance(c, ast.stmt)]
            found += _imports(children, in_function)
    return found


def read_module(name: str, path: Path, names: dict[str, Path]) -> Module:
    """The imports of one module, as edges to the package's own modules."""
    mod = Module(name, path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node, in_function in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path)).body, False):
        edges = mod.late if in_function else mod.top
        if isinstance(node, ast.Import):
            edges.update(a.name for a in node.names if a.name in names)
            continue
        base = node.module or ""
        if node.level:  # relative: from the package, up level - 1 packages
            anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
            base = ".".join([*anchor, *([base] if base else [])])
        if base not in names:
            continue
        for alias in node.names:
            target = f"{base}.{alias.name}"
            if target in names:  # a submodule
                edges.add(target)
                continue
            edges.add(base)
            if alias.name.startswith("_") and not alias.name.startswith("__") and base != name:
                mod.private.append((node.lineno, base, alias.name))
    mod.top.discard(name)
    mod.late.discard(name)
    return mod


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def visit(start: str) -> None:
        # Iterative depth-first search: the package is deep enough to make recursion a risk.
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.append(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph.get(child, ())))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(groups)


def package_edges(modules: dict[str, Module]) -> dict[str, set[str]]:
    """Subpackage -> the subpackages it imports (module-level and function-level alike)."""

    def top(name: str) -> str:
        parts = name.split(".")
        return parts[1] if len(parts) > 1 else "(package)"

    edges: dict[str, set[str]] = defaultdict(set)
    for mod in modules.values():
        for target in mod.top | mod.late:
            if top(target) != top(mod.name):
                edges[top(mod.name)].add(top(target))
    return edges


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("package", nargs="?", default="motion_env", help="the package folder (default motion_env)")
    p.add_argument("--all", action="store_true", help="count the imports inside functions too")
    p.add_argument("--packages", action="store_true", help="also list the edges between subpackages")
    args = p.parse_args(argv)
    root = Path(args.package).resolve()
    if not (root / "__init__.py").is_file():
        p.error(f"{args.package}: not a package folder (no __init__.py)")
    names = module_names(root)
    modules = {name: read_module(name, path, names) for name, path in names.items()}
    graph = {name: mod.top | (mod.late if args.all else set()) for name, mod in modules.items()}
    found = circles(graph)
    kind = "counting function-level imports" if args.all else "at import time"
    edges = sum(len(v) for v in graph.values())
    print(f"{len(modules)} modules, {edges} import edges; {len(found)} circles {kind}")
    for group in found:
        print("  circle: " + " <-> ".join(group))
    private = [(mod, *item) for mod in modules.values() for item in mod.private]
    print(f"{len(private)} private names imported across modules")
    for mod, line, source, name in private:
        print(f"  {mod.path.relative_to(root.parent)}:{line} imports {name} from {source}")
    package_circles: list[list[str]] = []
    if args.packages:
        packages = package_edges(modules)
        package_circles = circles(packages)
        print(f"subpackages (imports inside functions included): {len(package_circles)} circles")
        for group in package_circles:
            print("  circle: " + " <-> ".join(group))
        for package, targets in sorted(packages.items()):
            print(f"  {package} -> {', '.join(sorted(targets))}")
    return 1 if found or private or package_circles else 0


if __name__ == "__main__":
    sys.exit(main())
