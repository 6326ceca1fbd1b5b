"""
The tests' program files: four taught points of a pick and place, and programs over them.

The points are joint positions whose tool poses are 10 cm either side of the x axis, the tool
pointing down (B = pi/2): ``above_*`` at z = 0.25 m, ``pick`` and ``place`` 7 cm below them.
"""

import os
import textwrap

POINTS = {
    'above_pick': [0.343, 0.0601, 0.4075, 0.0, 1.1032, -0.343],
    'pick': [0.343, 0.2031, 0.5072, 0.0, 0.8605, -0.343],
    'above_place': [-0.343, 0.0601, 0.4075, 0.0, 1.1032, 0.343],
    'place': [-0.343, 0.2031, 0.5072, 0.0, 0.8605, 0.343],
}

# lin down at 0.05 m/s, lin up, ptp across with a blend, lin down, lin up; repeated.
PICK_AND_PLACE = """\
program: pick_and_place
points: points.yaml
steps:
  - ptp: above_pick
  - repeat: {repeat}
    steps:
      - lin: pick
        speed: 0.05
{gripper_close}
      - lin: above_pick
        speed: 0.05
        blend: {blend}
      - ptp: above_place
        blend: {blend}
      - lin: place
        speed: 0.05
{gripper_open}
      - lin: above_place
        speed: 0.05
"""


def points_text(points: dict = POINTS) -> str:
    """Return a points file of ``points`` (name: joints)."""
    lines = ['points:']
    for name, q in points.items():
        lines += [f'  {name}:', '    joints: [' + ', '.join(str(v) for v in q) + ']']
    return '\n'.join(lines) + '\n'


def pick_and_place(repeat: int = 3, blend: float = 0.02, gripper: bool = False) -> str:
    """Return the pick and place program (``gripper``: close after pick, open after place)."""
    close = '      - gripper: close' if gripper else ''
    opened = '      - gripper: open' if gripper else ''
    text = PICK_AND_PLACE.format(repeat=repeat, blend=blend, gripper_close=close,
                                 gripper_open=opened)
    return '\n'.join(line for line in text.splitlines() if line) + '\n'


def write_program(folder, text: str, name: str = 'program.yaml', points: dict = POINTS) -> str:
    """Write ``points.yaml`` and the program ``text`` (dedented) into ``folder``; its path."""
    with open(os.path.join(folder, 'points.yaml'), 'w', encoding='utf-8') as f:
        f.write(points_text(points))
    path = os.path.join(folder, name)
    with open(path, 'w', encoding='utf-8') as f:
        f.write(textwrap.dedent(text))
    return path
