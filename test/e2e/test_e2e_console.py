"""
The web console in a real browser: headless Chromium drives the page against the running stack.

The stack (MuJoCo bridge, controller, planner) and the console run as processes; the
distribution's Chromium (``chromium`` and ``chromedriver``, which ``./run.sh test`` installs
where missing) loads the page, a goal is typed into the page's own number fields, Plan shows
the planned path, Go sends it, and the arm's arrival is judged from /joint_states. A refused
goal shows its reason on the page and moves nothing. Screenshots and the nodes' logs go to the
test's output folder: ``$MOVER6_TEST_OUTPUT/console_e2e`` when that is set, else pytest's
temporary folder (printed; ``pytest -s`` shows it).
"""

import os
import pathlib
import shutil
import socket
import tempfile

from mover6_control.kinematics.arm import mover6
from mover6_control.kinematics.forward import fk
from mover6_control.resources import executable_command
from mover6_control.tools.goal_cli import GoalClient
from mover6_control.tools.goal_convention import pose_from_goal
import numpy as np
import pytest
from ros_testing import NodeProcess, ready_client, Stack

pytestmark = pytest.mark.e2e

CHROMIUM, CHROMEDRIVER = '/usr/bin/chromium', '/usr/bin/chromedriver'
FLAGS = ('--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
         '--disable-background-networking', '--disable-component-update', '--disable-sync',
         '--disable-dev-shm-usage', '--window-size=1400,900')
ARM = mover6()
GOAL = (0.30, -0.08, 0.32, 0.0, 0.0, 0.0)          # X Y Z A B C, the Mover6 report's convention
OUT_OF_REACH = (0.90, 0.0, 0.40, 0.0, 0.0, 0.0)
LABELS = ('X [m]', 'Y [m]', 'Z [m]', 'A [rad]', 'B [rad]', 'C [rad]')


def free_port():
    """Return a TCP port free on 127.0.0.1 now."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture(scope='module')
def webdriver_module():
    """Return selenium's webdriver, or skip (with what is missing) where there is no browser."""
    selenium = pytest.importorskip('selenium', reason='selenium (requirements/test.txt)')
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not os.access(p, os.X_OK)]
    if missing:
        pytest.skip(f'no {" ".join(missing)}: apt-get install chromium chromium-driver '
                    '(./run.sh setup does it as root)')
    from selenium import webdriver
    assert selenium
    return webdriver


@pytest.fixture(scope='module')
def out_dir(tmp_path_factory):
    """Return the folder of this module's logs and screenshots."""
    chosen = os.environ.get('MOVER6_TEST_OUTPUT')
    if chosen:
        folder = pathlib.Path(chosen) / 'console_e2e'
        folder.mkdir(parents=True, exist_ok=True)
    else:
        folder = tmp_path_factory.mktemp('console_e2e')
    print(f'\nconsole e2e output: {folder}')
    return folder


@pytest.fixture(scope='module')
def stack(out_dir):
    """Start sim_bridge, controller and planner, and the console on a free port."""
    port = free_port()
    with Stack(out_dir) as running:
        running.nodes['console'] = NodeProcess(
            'console', out_dir, command=executable_command('console') + ['--port', str(port)])
        running.url = f'http://127.0.0.1:{port}/'
        yield running


@pytest.fixture(scope='module')
def client(stack):
    """Return a client that reads /joint_states, once every node answers."""
    with ready_client(stack, lambda: GoalClient(name='console_e2e_client')) as node:
        yield node


@pytest.fixture(scope='module')
def browser(webdriver_module, stack, client):
    """Return headless Chromium on the console's page (a fresh profile), once it shows."""
    from selenium.webdriver.chrome.service import Service
    options = webdriver_module.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tempfile.mkdtemp(prefix='console_e2e_chromium_')
    for flag in FLAGS + (f'--user-data-dir={profile}',):
        options.add_argument(flag)
    driver = webdriver_module.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        page = Page(driver)
        client.spin_until(lambda: page.opened(stack.url), 30.0)
        assert page.wait_text('planner: OK', 30.0), f'{page.text()}\n{stack.report()}'
        yield page
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


class Page:
    """The console's page in the browser: its number fields, buttons and text."""

    def __init__(self, driver):
        self.driver = driver

    def opened(self, url):
        """Load ``url`` once the console serves it; return True when the page shows its goal."""
        from selenium.common.exceptions import WebDriverException
        try:
            if not self.driver.current_url.startswith(url):
                self.driver.get(url)
            return bool(self.field('X [m]'))
        except WebDriverException:
            return False

    def text(self):
        """Return the page's visible text."""
        from selenium.webdriver.common.by import By
        return self.driver.find_element(By.TAG_NAME, 'body').text

    def wait_text(self, part, timeout):
        """Wait until the page's text holds ``part``; return True when it did."""
        from selenium.common.exceptions import TimeoutException
        from selenium.webdriver.support.ui import WebDriverWait
        try:
            WebDriverWait(self.driver, timeout, poll_frequency=0.1).until(
                lambda _: part in self.text())
            return True
        except TimeoutException:
            return False

    def field(self, label):
        """Return the input field labelled ``label`` (None while the page has none)."""
        from selenium.webdriver.common.by import By
        found = self.driver.find_elements(
            By.XPATH, f"//label[normalize-space()='{label}']/ancestor::div[.//input][1]//input")
        return found[0] if found else None

    def type_goal(self, numbers):
        """Type X Y Z A B C into the page's fields, as a user does (select, type, Tab)."""
        from selenium.webdriver.common.keys import Keys
        for label, value in zip(LABELS, numbers):
            field = self.field(label)
            field.click()
            field.send_keys(Keys.CONTROL, 'a')
            field.send_keys(Keys.BACKSPACE)
            field.send_keys(f'{value:g}', Keys.TAB)
            shown = field.get_attribute('value')
            assert float(shown) == value, f'{label}: typed {value:g}, the field shows {shown}'

    def press(self, label):
        """Click the button labelled ``label``."""
        from selenium.webdriver.common.by import By
        buttons = [b for b in self.driver.find_elements(By.TAG_NAME, 'button')
                   if b.text == label]
        assert buttons, f'no button {label!r} on the page'
        buttons[0].click()

    def shot(self, path):
        """Save a screenshot to ``path``."""
        assert self.driver.save_screenshot(str(path))
        print(f'screenshot: {path}')


def fresh_q(client):
    """Return joint positions received from now on (the client keeps only the latest)."""
    client.q = None
    assert client.spin_until(lambda: client.q is not None, 10.0)
    return client.q.copy()


def flange_error(q, numbers):
    """Return the distance [m] of the flange at ``q`` from the goal ``numbers``."""
    return float(np.linalg.norm(fk(ARM, q)[:3, 3] - pose_from_goal(ARM, *numbers)[:3, 3]))


def test_a_goal_typed_in_the_page_is_planned_and_reached(stack, client, browser, out_dir):
    """Type a goal, Plan (the path, nothing moves), Go: the arm arrives on /joint_states."""
    q_start = fresh_q(client)
    client.last_demands = None
    browser.type_goal(GOAL)
    browser.press('Plan')
    assert browser.wait_text('Plan: planned', 30.0), f'{browser.text()}\n{stack.report()}'
    # Plan sends nothing: no demand (a stray one would come within the second), the arm stays.
    client.spin_until(lambda: client.last_demands is not None, 1.0)
    assert client.last_demands is None
    assert np.abs(fresh_q(client) - q_start).max() < 1e-3
    browser.shot(out_dir / 'console_plan.png')
    browser.press('Go')
    assert browser.wait_text('the planner says planned', 30.0), \
        f'{browser.text()}\n{stack.report()}'
    arrived = client.spin_until(
        lambda: client.q is not None and flange_error(client.q, GOAL) < 0.003, 60.0)
    assert arrived, f'flange {flange_error(client.q, GOAL):.4f} m from the goal\n' \
        f'{stack.report()}'
    assert browser.wait_text('result arrived', 10.0), browser.text()
    # The planner's demand for it (the path the page drew) reached this client too.
    assert client.spin_until(lambda: client.last_demands is not None, 5.0)
    # ... and the arm settles on its last waypoint (the flange came within 3 mm while moving).
    assert client.spin_until(
        lambda: np.abs(client.last_demands[-1] - client.q).max() < 0.01, 5.0), \
        np.abs(client.last_demands[-1] - client.q)
    browser.shot(out_dir / 'console_arrived.png')


def test_a_refused_goal_shows_its_reason_and_nothing_moves(stack, client, browser, out_dir):
    """A goal out of reach: Plan and the planner's answer to Go both show the reason."""
    # The motion before has ended (the controller is idle again): the arm rests.
    assert browser.wait_text('state idle', 30.0), browser.text()
    q_start = fresh_q(client)
    earlier = client.last_demands         # the goal before's (the planner may send it again)
    browser.type_goal(OUT_OF_REACH)
    browser.press('Plan')
    assert browser.wait_text('Plan: refused (out_of_reach)', 30.0), browser.text()
    browser.press('Go')
    assert browser.wait_text('the planner refused the goal (out_of_reach)', 30.0), \
        f'{browser.text()}\n{stack.report()}'
    browser.shot(out_dir / 'console_refused.png')

    def new_demand():
        return client.last_demands is not None and (
            earlier is None or not np.array_equal(client.last_demands, earlier))
    client.spin_until(new_demand, 1.0)
    assert not new_demand(), f'a demand after the refused goal:\n{client.last_demands}'
    assert np.abs(fresh_q(client) - q_start).max() < 1e-3


def test_a_second_tab_sees_the_same_page(stack, browser):
    """A second tab opened now shows the goal and the answer the first one gave."""
    first = browser.driver.current_window_handle
    browser.driver.switch_to.new_window('tab')
    try:
        browser.driver.get(stack.url)
        assert browser.wait_text('the planner refused the goal (out_of_reach)', 30.0), \
            browser.text()
        assert browser.field('X [m]').get_attribute('value') == '0.9'
    finally:
        browser.driver.close()
        browser.driver.switch_to.window(first)
