"""
The package drawn as a house: each layer a room, each module a cell in it, arrows for imports.

Read from the source with :mod:`ast` (no module of the package is imported), so the picture
and the edge list are the code's own imports: ``import a.b`` names ``a.b``; ``from a import b``
names ``a.b`` when that is a module, else ``a``; relative imports are resolved against the
module's package; imports inside functions count like those at module level.

``python -m train_dynamics.house`` writes ``docs/figures/house.png`` and beside it
``docs/figures/house.txt`` (the rooms, their modules, the arrows between rooms with the number
of module-to-module imports each carries, and the third-party packages each room imports);
``test/package/test_house.py`` fails when the text falls behind the code or an arrow breaks
the layer rules of ``MAY_IMPORT``. Only :func:`draw` needs matplotlib, imported there.
"""
from __future__ import annotations

import ast
from collections import Counter
from dataclasses import dataclass
import hashlib
from pathlib import Path
import sys

PACKAGE = Path(__file__).resolve().parent
FIGURE = PACKAGE.parent / 'docs' / 'figures' / 'house.png'
EDGES = FIGURE.with_suffix('.txt')

#: rooms from the top floor down; a module is in the first room whose folder holds it
#: (``top-level``: the package's own ``*.py`` files and its ``__init__``)
FLOORS = (
    ('testing',),
    ('ros', 'cli'),
    ('recording',),
    ('simulation',),
    ('physics',),
    ('physics/config', 'physics/kernel'),
    ('top-level',),
)
ROOMS = tuple(room for floor in FLOORS for room in floor)
#: the ground floor, which most rooms import: only arrows from the floors next to it are drawn
GROUND = 'top-level'

_PHYSICS = {'physics', 'physics/config', 'physics/kernel'}
_BELOW_ROS = {'top-level', 'simulation', 'recording'} | _PHYSICS
#: room -> the rooms it may import (docs/development.md, "Layout and layers")
MAY_IMPORT = {
    'top-level': _PHYSICS,
    'physics': {'top-level', 'physics/config', 'physics/kernel'},
    'physics/config': {'top-level', 'physics', 'physics/kernel'},
    'physics/kernel': {'top-level', 'physics', 'physics/config'},
    'simulation': {'top-level'} | _PHYSICS,
    'recording': {'top-level', 'simulation'} | _PHYSICS,
    'ros': _BELOW_ROS,
    'cli': _BELOW_ROS,
    'testing': _BELOW_ROS | {'ros', 'cli'},
}
#: third-party packages only some rooms may import: package -> those rooms
ONLY_IN = {
    'rclpy': {'ros'},
    'rosbags': {'recording', 'ros', 'cli', 'testing'},
    'matplotlib': {'recording', 'cli', 'testing', 'top-level'},
}


@dataclass(frozen=True)
class Module:
    """One module of the package: its dotted name, room, file and length (lines)."""

    name: str
    room: str
    path: Path
    lines: int


def room_of(name: str) -> str:
    """Return the room of dotted module ``name`` (``train_dynamics.physics.kernel.step``)."""
    parts = name.split('.')[1:]
    if len(parts) >= 2 and '/'.join(parts[:2]) in ROOMS:
        return '/'.join(parts[:2])
    if len(parts) >= 2 and parts[0] in ROOMS:
        return parts[0]
    if parts and parts[0] in ROOMS:         # a folder's __init__
        return parts[0]
    return 'top-level'


def modules(root: Path = PACKAGE) -> dict[str, Module]:
    """Return ``{dotted name: Module}`` of every ``*.py`` file under ``root``."""
    out = {}
    for path in sorted(root.rglob('*.py')):
        parts = list(path.relative_to(root.parent).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts.pop()
        name = '.'.join(parts)
        lines = len(path.read_text(encoding='utf-8').splitlines())
        out[name] = Module(name, room_of(name), path, lines)
    return out


def imports_of(name: str, path: Path, known) -> tuple[set[str], set[str]]:
    """
    Return (the package's modules, the other top-level packages) that module ``name`` imports.

    ``known``: the package's module names (anything supporting ``in``). ``import a.b`` -> a.b;
    ``from a import b`` -> a.b when that is a module, else a; relative imports resolved
    against the module's package; imports anywhere in the module count.
    """
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    own, other = set(), set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')[:len(package.split('.')) - node.level + 1]
                base = '.'.join(anchor + ([base] if base else []))
            names = [f'{base}.{a.name}' if f'{base}.{a.name}' in known else base
                     for a in node.names]
        else:
            continue
        for target in names:
            if target in known:
                if target != name:
                    own.add(target)
            elif target.split('.')[0] != name.split('.')[0]:
                other.add(target.split('.')[0])
    return own, other


@dataclass(frozen=True)
class House:
    """The rooms' modules, the arrows between rooms and each room's third-party imports."""

    modules: dict
    arrows: dict            # (from room, to room) -> number of module-to-module imports
    third_party: dict       # room -> sorted non-standard-library packages it imports

    def text(self) -> str:
        """Return the edge list written beside the figure (one fact a line, sorted)."""
        lines = []
        for room in ROOMS:
            names = sorted(m.name for m in self.modules.values() if m.room == room)
            lines.append(f'room {room}: ' + ' '.join(n.rsplit('.', 1)[-1] for n in names))
        for (a, b), n in sorted(self.arrows.items()):
            lines.append(f'arrow {a} -> {b}: {n}')
        for room in ROOMS:
            lines.append(f'uses {room}: ' + ' '.join(self.third_party.get(room, [])))
        return '\n'.join(lines) + '\n'

    def digest(self) -> str:
        """Return the SHA-256 of :meth:`text`, written into the figure it draws."""
        return hashlib.sha256(self.text().encode()).hexdigest()


def house(root: Path = PACKAGE) -> House:
    """Read the house of the package at ``root`` (nothing is imported)."""
    mods = modules(root)
    arrows: Counter = Counter()
    third: dict[str, set[str]] = {}
    for name, mod in mods.items():
        own, other = imports_of(name, mod.path, mods)
        for target in own:
            if mods[target].room != mod.room:
                arrows[mod.room, mods[target].room] += 1
        stdlib = sys.stdlib_module_names
        third.setdefault(mod.room, set()).update(
            o for o in other if o not in stdlib and not o.startswith('_') and o != '__future__')
    return House(mods, dict(arrows), {r: sorted(s) for r, s in third.items()})


def figure_digest(path: Path = FIGURE) -> str:
    """Return the digest a figure of :func:`draw` carries (its PNG ``tEXt`` Description)."""
    data = path.read_bytes()
    at = 8                                   # after the PNG signature
    while at + 8 <= len(data):
        size = int.from_bytes(data[at:at + 4], 'big')
        kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + size]
        if kind == b'tEXt' and body.startswith(b'Description\0'):
            return body.split(b'\0', 1)[1].decode('latin-1')
        at += 12 + size                      # length, type, data, CRC
    return ''


def broken_rules(h: House) -> list[str]:
    """Return one line per arrow or third-party import that the layer rules forbid."""
    bad = [f'{a} imports {b}' for (a, b) in sorted(h.arrows) if b not in MAY_IMPORT[a]]
    for room, packages in sorted(h.third_party.items()):
        bad += [f'{room} imports {p}' for p in packages
                if p in ONLY_IN and room not in ONLY_IN[p]]
    return bad


_WIDTH = 100.0              # figure units across
_FLOOR = 11.0               # a floor's height, figure units
_GAP = 7.0                  # between floors, for the arrows
_DOWN, _UP, _SIDE = '#3b4a5a', '#c08a1e', '#6f8fb0'


def _layout(h: House) -> dict[str, tuple[float, float, float, float]]:
    """Return ``{room: (x, y, width, height)}``: floors top-down, width by lines (min 14)."""
    size = {r: sum(m.lines for m in h.modules.values() if m.room == r) for r in ROOMS}
    boxes = {}
    for level, floor in enumerate(FLOORS):
        widths = [max(14.0, 100.0 * size[r] / max(size.values())) for r in floor]
        scale = min(1.0, (_WIDTH - 4.0 * (len(floor) - 1)) / sum(widths))
        widths = [w * scale for w in widths]
        x = (_WIDTH - sum(widths) - 4.0 * (len(floor) - 1)) / 2
        y = -level * (_FLOOR + _GAP)
        for room, w in zip(floor, widths):
            boxes[room] = (x, y, w, _FLOOR)
            x += w + 4.0
    return boxes


def _spots(n: int, x: float, w: float) -> list[float]:
    """Return ``n`` points spread along the middle of a room's edge from ``x`` over ``w``."""
    return [x + w * (0.2 + 0.6 * (i + 0.5) / n) for i in range(n)]


def draw(h: House, out: Path) -> None:
    """Draw the house (rooms, a cell per module, width by its lines; arrows) into ``out``."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot as plt
    from matplotlib.patches import FancyArrowPatch, Rectangle

    boxes = _layout(h)
    fig, ax = plt.subplots(figsize=(16, 13))
    floor_of = {r: i for i, f in enumerate(FLOORS) for r in f}
    for room, (x, y, w, hgt) in boxes.items():
        mods = sorted((m for m in h.modules.values() if m.room == room),
                      key=lambda m: (-m.lines, m.name))
        total = sum(m.lines for m in mods)
        ax.add_patch(Rectangle((x, y), w, hgt, fc='#eef2f6', ec='#3b4a5a', lw=1.2))
        ax.text(x + 0.4, y + hgt - 0.4, f'{room}/' if room != 'top-level' else room,
                va='top', fontsize=10, weight='bold')
        ax.text(x + w - 0.4, y + hgt - 0.4, f'{len(mods)} modules, {total} lines',
                va='top', ha='right', fontsize=7, color='#555555')
        uses = ', '.join(h.third_party.get(room, [])) or 'no third-party package'
        ax.text(x + 0.4, y + 0.3, uses, fontsize=5.5, color='#777777', va='bottom')
        weights = [max(m.lines, total * 0.012) for m in mods]
        cx, inner = x + 0.4, w - 0.8
        for mod, wt in zip(mods, weights):
            cw = inner * wt / sum(weights)
            ax.add_patch(Rectangle((cx, y + 1.2), cw, hgt - 3.0, fc='#c3d5e6', ec='white',
                                   lw=0.6))
            label = mod.name.rsplit('.', 1)[-1] if mod.name.count('.') > room.count('/') + 1 \
                else '__init__'
            if room == 'top-level':
                label = mod.name.rsplit('.', 1)[-1] if mod.name != 'train_dynamics' \
                    else '__init__'
            ax.text(cx + cw / 2, y + 1.4, f'{label} {mod.lines}', rotation=90, ha='center',
                    va='bottom', fontsize=5.5 if cw > 0.9 else 4.5, clip_on=True)
            cx += cw
    ground = {ab: n for ab, n in h.arrows.items()
              if ab[1] == GROUND and floor_of[ab[0]] < floor_of[GROUND] - 2}
    drawn = {ab: n for ab, n in h.arrows.items() if ab not in ground}
    outgoing = {r: sorted(b for a, b in drawn if a == r) for r in ROOMS}
    incoming = {r: sorted(a for a, b in drawn if b == r) for r in ROOMS}
    x, y, w, _ = boxes[GROUND]
    ax.text(x + w + 1.0, y + 0.5, 'also imported, arrows not drawn, by\n' + '\n'.join(
        f'{a}/: {n}' for (a, _), n in sorted(ground.items())), fontsize=7, color=_DOWN)
    for (a, b), n in sorted(drawn.items()):
        xa, ya, wa, ha = boxes[a]
        xb, yb, wb, hb = boxes[b]
        sa = _spots(len(outgoing[a]), xa, wa)[outgoing[a].index(b)]
        sb = _spots(len(incoming[b]), xb, wb)[incoming[b].index(a)]
        if floor_of[a] == floor_of[b]:
            start, end, colour = (sa, ya), (sb, yb), _SIDE
            rad = 0.35 if sb > sa else -0.35            # bends below the floor
        elif floor_of[a] < floor_of[b]:
            start, end, colour, rad = (sa, ya), (sb, yb + hb), _DOWN, 0.0
        else:
            start, end, colour, rad = (sa, ya + ha), (sb, yb), _UP, 0.0
        ax.add_patch(FancyArrowPatch(start, end, arrowstyle='-|>', mutation_scale=9,
                                     lw=0.6 + 0.5 * n ** 0.5, color=colour, alpha=0.8,
                                     connectionstyle=f'arc3,rad={rad}', zorder=0.5))
        dx, dy = end[0] - start[0], end[1] - start[1]
        along = min(0.5, 3.0 / max(1e-9, (dx * dx + dy * dy) ** 0.5))  # in the gap below
        at = (start[0] + dx * along, start[1] + dy * along) if colour != _SIDE \
            else (start[0] + dx * 0.1, start[1] - 2.5)
        ax.text(*at, str(n), fontsize=7,
                color=colour, ha='center', va='center', zorder=0.6,
                bbox={'fc': 'white', 'ec': 'none', 'pad': 0.5})
    n_lines = sum(m.lines for m in h.modules.values())
    ax.set_title(f'train_dynamics: {len(h.modules)} modules, {n_lines} lines, '
                 f'{len(h.arrows)} arrows between {len(ROOMS)} rooms', loc='left', fontsize=12)
    ax.text(0, boxes['top-level'][1] - 2.0,
            'a room per layer, a cell per module (its width by its lines, its name and lines); '
            'an arrow from a room to a room it imports, with the number of module-to-module '
            'imports it carries (to the ground from far floors: listed beside it)\n'
            'dark: down to a lower floor (behind the rooms it passes); ochre: up; blue: across a '
            'floor. Grey under each '
            'room: the third-party packages it imports. Drawn from the imports in the source '
            '(ast): python -m train_dynamics.house', fontsize=7,
            va='top', color='#444444')
    ax.set_xlim(-1, _WIDTH + 1)
    ax.set_ylim(boxes['top-level'][1] - 5, _FLOOR + 3)
    ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(out, dpi=100, metadata={'Software': None, 'Description': h.digest()})
    plt.close(fig)


if __name__ == '__main__':       # pragma: no cover
    built = house()
    EDGES.write_text(built.text(), encoding='utf-8')
    draw(built, FIGURE)
    print(f'wrote {FIGURE} and {EDGES}')
