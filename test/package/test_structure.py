"""The package's structure: no import cycle between its modules."""
from pathlib import Path

from train_dynamics.house import imports_of

PACKAGE = Path(__file__).resolve().parents[2] / 'train_dynamics'


def module_names(root: Path = PACKAGE) -> dict[str, Path]:
    """Return ``{dotted module name: file}`` of every module of the package."""
    out = {}
    for path in sorted(root.rglob('*.py')):
        parts = list(path.relative_to(root.parent).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts.pop()
        out['.'.join(parts)] = path
    return out


def import_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    """Return ``{module: the package's modules it imports}``."""
    modules = module_names(root)
    return {name: imports_of(name, path, modules)[0] for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """Return one import cycle (``[a, b, ..., a]``), or None (depth-first search)."""
    state: dict[str, int] = {}       # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state:
            cycle = visit(start)
            if cycle:
                return cycle
    return None


def test_no_import_cycle_in_the_package():
    """Every module's imports (module level or in functions) form no cycle."""
    graph = import_graph()
    assert 'train_dynamics.physics.train' in graph     # the walk sees the package
    cycle = find_cycle(graph)
    assert cycle is None, 'import cycle: ' + ' -> '.join(cycle)


def test_the_cycle_finder_finds_a_cycle(tmp_path):
    """A package whose modules import each other (one relatively, one in a function) fails."""
    pkg = tmp_path / 'pkg'
    (pkg / 'sub').mkdir(parents=True)
    (pkg / '__init__.py').write_text('')
    (pkg / 'sub' / '__init__.py').write_text('')
    (pkg / 'a.py').write_text('from pkg.sub import b\n')
    (pkg / 'sub' / 'b.py').write_text('def f():\n    from .. import c\n')
    (pkg / 'c.py').write_text('import pkg.a\n')
    (pkg / 'd.py').write_text('from pkg import a\n')
    graph = import_graph(pkg)
    assert graph['pkg.d'] == {'pkg.a'}
    assert find_cycle(graph) == ['pkg.a', 'pkg.sub.b', 'pkg.c', 'pkg.a']
    (pkg / 'c.py').write_text('')
    assert find_cycle(import_graph(pkg)) is None
