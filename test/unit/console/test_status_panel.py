"""The console's status panel text, from plain values (no browser)."""

from mover6_control.nodes.console.status_panel import estop, PanelState, ShownStatus, status_html


def joints(flag_names):
    return tuple(ShownStatus('OK', 'enabled', {
        'name': f'joint{k + 1}', 'state': 'enabled', 'flags': '0x00', 'flag_names': names,
        'referenced': 'True'}) for k, names in enumerate(flag_names))


def test_missing_nodes_are_named():
    text = status_html(PanelState(missing=('the planner (planner/status has no publisher)',)))
    assert 'missing: the planner' in text
    assert 'controller</b>: <span style="color:#6e7781">no status yet' in text


def test_statuses_and_the_tick_health_are_shown():
    controller = ShownStatus('OK', 'idle', {'state': 'idle', 'max_tick_gap': '0.2000',
                                            'max_states_age': '0.0100'})
    planner = ShownStatus('ERROR', 'goal refused (out_of_reach): far', {
        'state': 'ready', 'result': 'refused', 'reason': 'out_of_reach'})
    text = status_html(PanelState(controller=controller, planner=planner))
    assert 'state <code>idle</code>' in text
    assert 'color:#d1242f">0.2000 s' in text           # a late tick is red
    assert 'out_of_reach' in text and 'refused' in text
    assert 'E-STOP' not in text and 'Driver' not in text


def test_the_estop_shows_red_with_a_driver():
    bus = ShownStatus('ERROR', 'holding', {'hold': ''})
    pressed = PanelState(driver=bus, joints=joints(['estop_or_low_supply'] * 6))
    assert estop(pressed)
    text = status_html(pressed)
    assert 'id="mover6-estop"' in text and 'background:#d1242f' in text
    assert text.count('<tr>') == 7                         # a header and six joints
    released = PanelState(driver=bus, joints=joints([''] * 6))
    assert not estop(released) and 'E-STOP' not in status_html(released)


def test_text_from_the_graph_is_escaped():
    text = status_html(PanelState(planner=ShownStatus('WARN', '<script>x</script>', {})))
    assert '<script>' not in text and '&lt;script&gt;' in text
