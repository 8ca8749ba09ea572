"""
The house of docs/development.md: its picture is of today's imports and they keep the layers.

``train_dynamics.house`` reads the imports with ast; the committed edge list
(``docs/figures/house.txt``) and the figure's embedded digest must be those of the code now.
"""
from pathlib import Path

from train_dynamics.house import broken_rules, figure_digest, house as read_house, MAY_IMPORT, \
    ROOMS

REPO = Path(__file__).resolve().parents[2]
FIGURE = REPO / 'docs' / 'figures' / 'house.png'
REGENERATE = 'regenerate: python -m train_dynamics.house'


def house(root: Path = REPO / 'train_dynamics'):
    """Return the house of the checkout's package (or of ``root``)."""
    return read_house(root)


def test_the_committed_edge_list_is_the_house_of_the_code():
    now = house()
    assert FIGURE.with_suffix('.txt').read_text(encoding='utf-8') == now.text(), REGENERATE


def test_the_committed_figure_was_drawn_from_the_same_house():
    assert figure_digest(FIGURE) == house().digest(), REGENERATE


def test_the_house_sees_every_room_and_the_known_arrows():
    h = house()
    assert {m.room for m in h.modules.values()} == set(ROOMS)
    assert h.modules['train_dynamics.physics.kernel.step'].room == 'physics/kernel'
    assert h.modules['train_dynamics.physics.config'].room == 'physics/config'
    assert h.modules['train_dynamics.topics'].room == 'top-level'
    # the node wires the physics; the train calls the compiled kernel
    assert h.arrows[('ros', 'physics')] >= 1
    assert h.arrows[('physics', 'physics/kernel')] >= 1


def test_every_arrow_keeps_the_layer_rules():
    h = house()
    assert not broken_rules(h)
    for low in ('physics', 'physics/config', 'physics/kernel', 'simulation'):
        assert not {b for a, b in h.arrows if a == low} & {'recording', 'ros', 'cli', 'testing'}
    assert ('recording', 'ros') not in h.arrows and ('cli', 'ros') not in h.arrows


def test_only_the_ros_room_imports_rclpy():
    h = house()
    assert [room for room, used in sorted(h.third_party.items()) if 'rclpy' in used] == ['ros']


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding='utf-8')


def test_a_forbidden_arrow_or_import_breaks_the_rules(tmp_path):
    pkg = tmp_path / 'pkg'
    _write(pkg, {
        '__init__.py': '',
        'topics.py': '',
        'physics/__init__.py': '',
        'physics/train.py': 'from pkg import topics\n',
        'physics/kernel/__init__.py': '',
        'physics/kernel/step.py': 'def f():\n    from ...ros import node\n',
        'ros/__init__.py': '',
        'ros/node.py': 'import rclpy\nfrom ..physics import train\n',
        'recording/__init__.py': '',
        'recording/bags.py': 'import rclpy.node\nimport rosbags\n',
    })
    h = house(pkg)
    assert h.arrows == {('physics', 'top-level'): 1, ('physics/kernel', 'ros'): 1,
                        ('ros', 'physics'): 1}
    assert broken_rules(h) == ['physics/kernel imports ros', 'recording imports rclpy']
    _write(pkg, {'physics/kernel/step.py': '', 'recording/bags.py': 'import rosbags\n'})
    assert broken_rules(house(pkg)) == []


def test_the_rules_name_every_room():
    assert set(MAY_IMPORT) == set(ROOMS)
    assert all(rooms <= set(ROOMS) for rooms in MAY_IMPORT.values())


def test_the_drawing_is_the_same_at_every_run_and_carries_its_digest(tmp_path):
    from train_dynamics.house import draw

    h = house()
    first, second = tmp_path / 'a.png', tmp_path / 'b.png'
    draw(h, first)
    draw(h, second)
    assert first.read_bytes() == second.read_bytes()
    assert figure_digest(first) == h.digest()
