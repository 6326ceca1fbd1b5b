"""
The console's status panel: the nodes' statuses, the tick's health, a driver's modules.

The controller's and the planner's status, the tick's health, what is missing from the graph,
and with a driver each joint's module flags, the referenced bit, the e-stop state (red) and the
driver's services as buttons.

``status_html`` makes the panel's text from plain values, so it is tested without a browser.
"""

from dataclasses import dataclass, field
import html
from typing import Callable, Optional

from mover6_control.nodes.controller.tick_loop import TICK_GAP_WARN   # a late tick, as logged
from viser import ViserServer

DRIVER_SERVICES = ('reset', 'enable', 'reference', 'disable')
ESTOP_FLAGS = ('estop_or_low_supply', 'brown_out')
LEVEL_COLOURS = {'OK': '#1a7f37', 'WARN': '#b58900', 'ERROR': '#d1242f', 'STALE': '#6e7781'}


@dataclass(frozen=True)
class ShownStatus:
    """One status as the panel shows it: level name, message and values (text)."""

    level: str
    message: str
    values: dict = field(default_factory=dict)


@dataclass(frozen=True)
class PanelState:
    """What the panel shows at one moment."""

    controller: Optional[ShownStatus] = None
    planner: Optional[ShownStatus] = None
    driver: Optional[ShownStatus] = None            # the bus
    joints: tuple = ()                         # one ShownStatus per joint of the driver
    missing: tuple = ()                        # what the graph lacks, as sentences
    last_action: str = ''


def estop(snapshot: PanelState) -> bool:
    """Return True when the driver says the e-stop was pressed (or the power went)."""
    flags = ' '.join(j.values.get('flag_names', '') for j in snapshot.joints).split()
    hold = snapshot.driver.values.get('hold', '') if snapshot.driver else ''
    return any(f in ESTOP_FLAGS for f in flags) or 'power lost' in hold


def _line(name: str, status: Optional[ShownStatus], absent: str) -> str:
    if status is None:
        return f'<b>{name}</b>: <span style="color:#6e7781">{html.escape(absent)}</span>'
    colour = LEVEL_COLOURS.get(status.level, '#000')
    return (f'<b>{name}</b>: <span style="color:{colour}">{status.level}</span> '
            f'{html.escape(status.message)}')


def status_html(snapshot: PanelState) -> str:
    """Return the panel's HTML for ``snapshot``."""
    rows = []
    if estop(snapshot):
        rows.append('<div id="mover6-estop" style="background:#d1242f;color:white;'
                    'padding:4px;font-weight:bold">E-STOP pressed or power lost: make the '
                    'arm safe, release the e-stop, then reset and enable</div>')
    for sentence in snapshot.missing:
        rows.append(f'<div style="color:#d1242f">missing: {html.escape(sentence)}</div>')
    rows.append(_line('controller', snapshot.controller, 'no status yet'))
    if snapshot.controller is not None:
        v = snapshot.controller.values
        rows.append(f'state <code>{html.escape(v.get("state", "?"))}</code>, motion '
                    f'<code>{html.escape(v.get("motion_id", "-"))}</code>, result '
                    f'<code>{html.escape(v.get("result", "-"))}</code>')
        gap = v.get('max_tick_gap')
        if gap is not None:
            try:
                late = float(gap) > TICK_GAP_WARN
            except ValueError:
                late = True
            colour = '#d1242f' if late else '#1a7f37'
            rows.append(f'tick: longest gap <span style="color:{colour}">{html.escape(gap)} s'
                        f'</span>, oldest states {html.escape(v.get("max_states_age", "?"))} s')
    rows.append(_line('planner', snapshot.planner, 'no status yet'))
    if snapshot.planner is not None:
        v = snapshot.planner.values
        rows.append(f'state <code>{html.escape(v.get("state", "?"))}</code>, last goal '
                    f'<code>{html.escape(v.get("goal_id", "-"))}</code> '
                    f'<code>{html.escape(v.get("result", "-"))}</code> '
                    f'{html.escape(v.get("reason", ""))}')
    if snapshot.driver is not None:
        rows.append(_line('driver', snapshot.driver, ''))
        rows.append('<table><tr><th>joint</th><th>state</th><th>flags</th>'
                    '<th>referenced</th></tr>' + ''.join(
                        f'<tr><td>{html.escape(j.values.get("name", ""))}'
                        f'</td><td>{html.escape(j.values.get("state", ""))}</td>'
                        f'<td>{html.escape(j.values.get("flags", ""))} '
                        f'{html.escape(j.values.get("flag_names", ""))}</td>'
                        f'<td>{html.escape(j.values.get("referenced", ""))}</td></tr>'
                        for j in snapshot.joints) + '</table>')
    if snapshot.last_action:
        rows.append(f'<div>{html.escape(snapshot.last_action)}</div>')
    return '<div style="font-size:0.85em">' + '<br>'.join(rows) + '</div>'


class StatusPanel:
    """The status text and, once a driver is seen, its service buttons."""

    def __init__(self, server: ViserServer, on_driver: Callable, wrap: Callable):
        """Build the panel; ``on_driver(kind)`` calls the driver's service ``kind``."""
        gui = server.gui
        with gui.add_folder('State'):
            self.text = gui.add_html(status_html(PanelState()))
            self.buttons = []
            for kind in DRIVER_SERVICES:
                button = gui.add_button(f'Driver: {kind}', visible=False,
                                        color='red' if kind == 'disable' else None)
                button.on_click(wrap(f'console driver {kind}',
                                     lambda _, kind=kind: on_driver(kind)))
                self.buttons.append(button)
        self.shown = None

    def show(self, snapshot: PanelState) -> None:
        """Show ``snapshot`` (nothing is sent when it did not change)."""
        text = status_html(snapshot)
        if text != self.shown:
            self.shown = text
            self.text.content = text
        for button in self.buttons:
            button.visible = snapshot.driver is not None
