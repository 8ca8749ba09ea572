"""
Where a fact is written, and the largest module, class and function of each layer.

``python bench/fact_places.py [TREE ...]`` (default: this checkout) prints, for each tree:

- per layer (``physics`` = the files directly in ``physics/``, ``physics/config``,
  ``physics/kernel``, ``simulation``, ``recording``, ``ros``, ``cli``, ``testing``,
  ``top-level`` = ``train_dynamics/*.py``): the largest module (lines of the file), the largest
  class and the largest function or method (lines from ``def``/``class`` to the end of its
  body, ``ast`` ``end_lineno - lineno + 1``, decorators not counted);
- per fact (a string as the code spells it): in ``train_dynamics/``, the files whose code
  holds it in a string literal (docstrings left out: a literal is a place the fact is written,
  as a key, a topic, a table row or a message), the number of such literals, and the files
  that name it only through a module constant holding it (``VEHICLE_MOTION_TOPIC =
  'vehicle_motion'`` found in the tree, then ``topics.VEHICLE_MOTION_TOPIC`` elsewhere); in
  ``README.md`` and ``docs/*.md``, the pages and the lines that name it.

Nothing of the tree is imported: the sources are read with ``ast`` and ``tokenize``.
"""
from __future__ import annotations

import argparse
import ast
import io
from pathlib import Path
import re
import tokenize

LAYERS = ('physics', 'physics/kernel', 'physics/config', 'simulation', 'recording', 'ros',
          'cli', 'testing', 'top-level')

#: fact -> (kind, regex a string literal of the code must match, regex for a docs line)
FACTS = {
    'vehicle_motion': ('output topic', r'^vehicle_motion$', r'\bvehicle_motion\b'),
    'brake_blending': ('output topic', r'^brake_blending$', r'\bbrake_blending\b'),
    'brake_ep/command': ('controller input', r'^brake_ep/command$', r'brake_ep/command'),
    'traction/command': ('controller input', r'traction/command$', r'traction/command'),
    'record_flush_period': ('node parameter', r'^record_flush_period$',
                            r'\brecord_flush_period\b'),
    'brake_propagation_speed': ('simulator parameter', r'^brake_propagation_speed$',
                                r'\bbrake_propagation_speed\b'),
}


def layer_of(path: Path, package: Path) -> str:
    """Return the layer of a file of the package (see the module)."""
    parts = path.relative_to(package).parts
    if len(parts) == 1:
        return 'top-level'
    if parts[0] == 'physics' and len(parts) > 2:
        return f'physics/{parts[1]}'
    return parts[0]


def sizes(tree: Path) -> dict[str, dict[str, tuple[int, str]]]:
    """Return ``{layer: {'module'|'class'|'function': (lines, where)}}`` of the largest."""
    package = tree / 'train_dynamics'
    out: dict[str, dict[str, tuple[int, str]]] = {}
    for path in sorted(package.rglob('*.py')):
        text = path.read_text(encoding='utf-8')
        rel = str(path.relative_to(package))
        best = out.setdefault(layer_of(path, package), {})
        found = [('module', len(text.splitlines()), rel)]
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                kind = 'class' if isinstance(node, ast.ClassDef) else 'function'
                found.append((kind, node.end_lineno - node.lineno + 1, f'{rel}:{node.name}'))
        for kind, lines, where in found:
            if lines > best.get(kind, (0, ''))[0]:
                best[kind] = (lines, where)
    return out


def _docstring_lines(text: str) -> set[int]:
    """Return the first line of every docstring of a module (its string token starts there)."""
    lines = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                lines.add(body[0].lineno)
    return lines


def literals(text: str) -> list[str]:
    """Return the values of the string literals of the code, docstrings left out."""
    skip = _docstring_lines(text)
    out = []
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.STRING and tok.start[0] not in skip:
            try:
                value = ast.literal_eval(tok.string)
            except (ValueError, SyntaxError):      # an f-string part: keep the raw text
                value = tok.string
            out.append(value if isinstance(value, str) else '')
    return out


def names(text: str) -> set[str]:
    """Return the identifiers of the code."""
    return {tok.string for tok in tokenize.generate_tokens(io.StringIO(text).readline)
            if tok.type == tokenize.NAME}


def constants_holding(pattern: str, sources: dict[str, str]) -> set[str]:
    """
    Return the module-level names that hold a string literal matching ``pattern``.

    A constant or function is a holder when its value or body spells such a literal or names
    another holder of its own module (``TRACTION_TOPIC = 'coach_{i}/traction/command'``, then
    ``def traction_topic(i)`` formatting it, ``TRACTION_TOPIC_PATTERN = re.compile(...)``).
    """
    out: set[str] = set()
    for text in sources.values():
        defs = []
        for node in ast.parse(text).body:
            if isinstance(node, ast.Assign):
                targets = [t.id for t in node.targets if isinstance(t, ast.Name)]
                defs.append((targets, node.value))
            elif isinstance(node, ast.FunctionDef):
                defs.append(([node.name], node))
        held: set[str] = set()
        while True:
            before = len(held)
            for targets, body in defs:
                if any((isinstance(c, ast.Constant) and isinstance(c.value, str)
                        and re.search(pattern, c.value))
                       or (isinstance(c, ast.Name) and c.id in held) for c in ast.walk(body)):
                    held.update(targets)
            if len(held) == before:
                break
        out |= held
    return out


def places(tree: Path) -> dict[str, dict[str, object]]:
    """Return per fact: the code files spelling it, literals, files via constants, docs."""
    package = tree / 'train_dynamics'
    sources = {str(p.relative_to(tree)): p.read_text(encoding='utf-8')
               for p in sorted(package.rglob('*.py'))}
    pages = [p for p in [tree / 'README.md', *sorted((tree / 'docs').glob('*.md'))]
             if p.exists()]
    out = {}
    for fact, (kind, code_re, docs_re) in FACTS.items():
        spelled, n_literals, via_constant = [], 0, []
        consts = constants_holding(code_re, sources)
        for rel, text in sources.items():
            hits = [s for s in literals(text) if re.search(code_re, s)]
            if hits:
                spelled.append(rel)
                n_literals += len(hits)
            elif consts & names(text):
                via_constant.append(rel)
        doc_lines = {str(p.relative_to(tree)): sum(
            1 for line in p.read_text(encoding='utf-8').splitlines() if re.search(docs_re, line))
            for p in pages}
        out[fact] = {'kind': kind, 'spelled': spelled, 'literals': n_literals,
                     'via_constant': via_constant, 'constants': sorted(consts),
                     'docs': {p: n for p, n in doc_lines.items() if n}}
    return out


def short(rel: str) -> str:
    """Return a file's path inside the package."""
    return rel.removeprefix('train_dynamics/')


def report(tree: Path) -> str:
    """Return the markdown report of one tree."""
    lines = [f'### {tree}', '', '| layer | largest module | largest class | largest function |',
             '| --- | --- | --- | --- |']
    table = sizes(tree)
    for layer in LAYERS:
        best = table.get(layer)
        if best is None:
            lines.append(f'| {layer} | (none) | | |')
            continue
        cells = [f'{best[k][1]} {best[k][0]}' if k in best else '-'
                 for k in ('module', 'class', 'function')]
        lines.append(f'| {layer} | ' + ' | '.join(cells) + ' |')
    lines += ['', '| fact | kind | code files spelling it (literals) | code files naming a '
              'holder (the holders) | docs pages (lines) |', '| --- | --- | --- | --- | --- |']
    for fact, p in places(tree).items():
        docs = p['docs']
        lines.append(
            f'| `{fact}` | {p["kind"]} | {len(p["spelled"])} ({p["literals"]}): '
            f'{", ".join(short(f) for f in p["spelled"])} | {len(p["via_constant"])} '
            f'({", ".join(p["constants"]) or "no holder"}): '
            f'{", ".join(short(f) for f in p["via_constant"])} | '
            f'{len(docs)} ({sum(docs.values())}): '
            + ', '.join(f'{k} {v}' for k, v in docs.items()) + ' |')
    return '\n'.join(lines) + '\n'


def main(argv: list[str] | None = None) -> None:
    """Print the report of each tree given (default: this checkout)."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('trees', nargs='*', type=Path,
                        default=[Path(__file__).resolve().parents[1]])
    for tree in parser.parse_args(argv).trees:
        print(report(tree.resolve()))


if __name__ == '__main__':
    main()
