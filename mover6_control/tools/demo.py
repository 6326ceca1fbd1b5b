"""
The showcase a new user runs first (``./run.sh demo``).

Starts the three nodes headless through ``scripts/launch.sh`` (with ``--hardware can-sim`` the
driver on the CAN-level Mover6 instead of sim_bridge, the vendor's joint limits and goals inside
them: ``CAN_SHOWCASE``) and sends, through the real nodes,
the Mover6 report's two examples (its linear example and its IK example), then a parabolic
move, a spline through via poses and a joint move home, then three goals that must be refused:
one at the table surface (the tool would go into the table: a collision), one out of reach and
one reachable only outside the joint limits (the closest pose inside them is printed). Goals
are written as the goal CLI reads them (X Y Z A B C, A B C relative to the home orientation, as
the Mover6 report). Records the run (``./run.sh record``'s recorder: a rosbag2 MCAP folder in the
report folder) and makes the report from that recording, as ``./run.sh report BAG`` does: plots
of what ran, an animation of the arm and a metrics table (Markdown and JSON). Exits 0 only when
every move arrived within tolerance, each refusal was refused for its reason and the simulator
reported no contact (/sim_bridge/contacts).
"""

import argparse
import os
import signal
import subprocess
import sys
import time
from typing import Callable, Optional, Sequence

from diagnostic_msgs.msg import DiagnosticStatus
from mover6_control.control.commands import JOG_UNITS
from mover6_control.control.status import MotionResult
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, mover6
from mover6_control.kinematics.forward import fk_batch
from mover6_control.motion.metrics import max_deviation_from_polyline
from mover6_control.nodes.runtime import local_dds
from mover6_control.nodes.runtime.qos import STATUS_QOS
from mover6_control.resources import CONFIG_DIR
from mover6_control.tools.goal_cli import GoalClient
from mover6_control.tools.goal_convention import (EXIT_REFUSED, format_numbers, format_outcome,
                                                  poses_from_numbers)
from mover6_control.tools.record import check_bag_path, default_path
from mover6_control.tools.report import make_report, write_files
import numpy as np
import rclpy
from sensor_msgs.msg import JointState

# The folder that holds config/ and scripts/: the repository, or share/mover6_control installed
# (two folders up from this file is mover6_control/ itself since the layers became folders).
ROOT = os.path.dirname(CONFIG_DIR)


class Step:
    """One showcase step: a goal and what must become of it ('arrived' or a refusal reason)."""

    def __init__(self, name, title, kind, params, poses, expect=MotionResult.ARRIVED):
        self.name = name          # file names and the metrics table
        self.title = title        # what the console says
        self.kind = kind          # 'pose' or 'path'
        self.params = params      # planner parameters set first
        self.poses = poses        # X Y Z A B C (A B C from home) per pose; the last is the goal
        self.expect = expect


# In order from home (q = 0) and back: each move starts where the one before ended.
SHOWCASE = (
    Step('report_linear', "the Mover6 report's linear example (10 cm along x, orientation kept)",
         'pose', {'motion': 'linear'}, [(0.445, 0.0, 0.4425, 0.0, 0.0, 0.0)]),
    Step('report_ik', "the Mover6 report's IK example (its one solution inside +-90 deg)",
         'pose', {'motion': 'linear'}, [(0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)]),
    Step('parabolic', 'a parabolic move (4 cm peak), tool pointing down', 'pose',
         {'motion': 'parabolic', 'peak_height': 0.04}, [(0.30, -0.08, 0.32, 0.0, 1.5708, 0.0)]),
    Step('spline', 'a spline through two via poses, tool pointing down', 'path',
         {'path_motion': 'spline'},
         [(0.28, -0.05, 0.30, 0.0, 1.5708, 0.0), (0.25, 0.0, 0.32, 0.0, 1.5708, 0.0),
          (0.22, 0.08, 0.28, 0.0, 1.5708, 0.0)]),
    Step('joint', 'a joint-space move back home', 'pose', {'motion': 'joint'},
         [(0.345, 0.0, 0.4425, 0.0, 0.0, 0.0)]),
    Step('table', 'a goal at the table surface, tool pointing down (must be refused: the tool '
         'would go into the table)', 'pose', {'motion': 'linear'},
         [(0.25, 0.0, 0.0, 0.0, 1.5708, 0.0)], expect='collision'),
    Step('out_of_reach', 'a goal out of reach (must be refused)', 'pose', {'motion': 'linear'},
         [(0.9, 0.0, 0.4, 0.0, 0.0, 0.0)], expect='out_of_reach'),
    # The IK example's position with the home orientation: its only solutions need joint3 at
    # 1.654 rad or beyond, past +-pi/2 (kinematics.reachability.check_pose).
    Step('joint_limits', 'a goal reachable only outside the joint limits (must be refused)',
         'pose', {'motion': 'linear'}, [(0.1, 0.1, 0.2, 0.0, 0.0, 0.0)], expect='joint_limits'),
)
# Through the driver the arm has the vendor's joint limits (limit_set hardware: the driver clamps
# every set-point to them), and there the tool-down goals above need joint 5 past its 60 deg
# (the IK example also joint 2 past -50 deg): the same showcase with goals inside them, and the
# IK example refused for the reason the real arm has.
CAN_SHOWCASE = (
    SHOWCASE[0],
    Step('report_ik', "the Mover6 report's IK example (must be refused on the vendor's limits: "
         'joint 2 at -52 deg, joint 5 at 68 deg)', 'pose', {'motion': 'linear'},
         [(0.1, 0.1, 0.2, 0.0, 1.5708, 0.0)], expect='joint_limits'),
    Step('parabolic', 'a parabolic move (4 cm peak), tool tilted down by 1 rad', 'pose',
         {'motion': 'parabolic', 'peak_height': 0.04}, [(0.30, -0.08, 0.32, 0.0, 1.0, 0.0)]),
    Step('spline', 'a spline through two via poses, tool tilted down by 0.5 rad', 'path',
         {'path_motion': 'spline'},
         [(0.38, -0.05, 0.38, 0.0, 0.5, 0.0), (0.36, 0.0, 0.40, 0.0, 0.5, 0.0),
          (0.34, 0.08, 0.36, 0.0, 0.5, 0.0)]),
) + SHOWCASE[4:]
JOINT_TOLERANCE = 0.01     # [rad] the demo's pass mark for the final joint error
# The arm behind the stack (scripts/launch.sh --hardware): what each choice starts.
STACKS = {'sim': 'sim_bridge', 'can-sim': 'can_sim (the CAN-level Mover6) with the driver'}
LIMIT_SET = {'sim': 'within_90_deg', 'can-sim': 'hardware'}


class Recorder:
    """Record /joint_states (time [s], q (6,), qd (6,)) into lists, and the sim's contacts."""

    def __init__(self, node, joint_names):
        self.joint_names = joint_names
        self.t, self.q, self.qd = [], [], []
        self.contacts = None     # the latest /sim_bridge/contacts values
        node.create_subscription(JointState, 'joint_states', self.on_msg, 100)
        node.create_subscription(DiagnosticStatus, 'sim_bridge/contacts', self.on_contacts,
                                 STATUS_QOS)

    def on_contacts(self, msg: DiagnosticStatus) -> None:
        """Keep the simulator's latest contact report."""
        self.contacts = {kv.key: kv.value for kv in msg.values}

    def on_msg(self, msg: JointState) -> None:
        """Store one sample, mapped by name."""
        index = {n: i for i, n in enumerate(msg.name)}
        try:
            self.q.append([msg.position[index[n]] for n in self.joint_names])
            self.qd.append([msg.velocity[index[n]] if msg.velocity else 0.0
                            for n in self.joint_names])
            self.t.append(time.monotonic())
        except (KeyError, IndexError):
            pass

    def segment(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (t - t0, q, qd) arrays of the samples between t0 and t1."""
        t = np.asarray(self.t)
        mask = (t >= t0) & (t <= t1)
        return t[mask] - t0, np.asarray(self.q)[mask], np.asarray(self.qd)[mask]


def start_stack(log_dir: str, env: dict, hardware: str = 'sim',
                jog_units: str = 'rad_per_s') -> subprocess.Popen:
    """Start scripts/launch.sh (the arm, controller, planner) in its own process group."""
    cmd = ['bash', os.path.join(ROOT, 'scripts', 'launch.sh'), '--log-dir', log_dir,
           '--hardware', hardware, '--limit-set', LIMIT_SET[hardware], '--jog-units', jog_units]
    # With can-sim, the shipped defaults of a real arm: a test that gave the simulated arm more
    # (silent cycles, watchdog, state age) would prove nothing about the real one.
    return subprocess.Popen(cmd, env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def start_recorder(bag: str, log_dir: str, env: dict) -> subprocess.Popen:
    """Start the recorder node writing ``bag`` (its output in log_dir/recorder.log)."""
    from mover6_control.tools.record import recorder_command
    log = open(os.path.join(log_dir, 'recorder.log'), 'w')
    return subprocess.Popen(recorder_command(bag), env=env, start_new_session=True,
                            stdout=log, stderr=subprocess.STDOUT)


def bag_size(bag: str) -> int:
    """Return the size [bytes] of the files of recording ``bag``."""
    return sum(os.path.getsize(os.path.join(bag, f)) for f in os.listdir(bag))


def stop_stack(proc: subprocess.Popen) -> None:
    """Stop launch.sh by its pid (it stops its nodes); insist after 15 s."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(15.0)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(5.0)


def run_step(client: GoalClient, recorder: Recorder, arm: ArmModel, step: Step,
             say: Callable[[str], None]) -> dict:
    """Run one showcase step; return its metrics row."""
    Ts = poses_from_numbers([v for p in step.poses for v in p], quat=False, arm=arm)
    goal = format_numbers(step.poses[-1])
    problem = (client.set_planner_parameters(step.params)
               or client.wait_ready(timeout=30.0, steady=0.5))
    if problem:
        return {'motion': step.name, 'goal': goal, 'result': 'failed', 'reason': problem}
    say(f'--- {step.title}: goal {goal}')
    t0 = time.monotonic()
    if step.kind == 'pose':
        outcome = client.send_pose(Ts[-1], timeout=60.0, progress=lambda s: say('  ' + s))
    else:
        outcome = client.send_path(Ts, timeout=60.0, progress=lambda s: say('  ' + s))
    t1 = time.monotonic()
    say('  ' + format_outcome(outcome, (arm, False, step.poses[-1][3:])))
    row = {'motion': step.name, 'goal': goal, 'result': outcome.figures.get('result') or (
        'refused' if outcome.code == EXIT_REFUSED else 'failed')}
    if outcome.code == EXIT_REFUSED:
        row['reason'] = outcome.figures.get('reason', outcome.text)
        row['message'] = outcome.text
        return row
    row.update({k: outcome.figures[k] for k in
                ('duration', 'final_joint_error', 'final_position_error')
                if k in outcome.figures})
    t, q, qd = recorder.segment(t0, t1)
    row['samples'] = {'t': t.tolist(), 'q': q.tolist(), 'qd': qd.tolist()}
    if client.last_demands is not None and len(q):
        planned = fk_batch(arm, client.last_demands)[:, :3, 3]
        realised = fk_batch(arm, q)[:, :3, 3]
        row['planned_path'] = planned.tolist()
        row['max_path_deviation'] = max_deviation_from_polyline(realised, planned)
    return row


def passed(rows: list[dict], steps: Sequence[Step]) -> bool:
    """Return True when every move arrived within tolerance and each refusal had its reason."""
    for row, step in zip(rows, steps):
        if step.expect != MotionResult.ARRIVED:
            if row['result'] != 'refused' or row.get('reason') != step.expect:
                return False
        elif (row['result'] != MotionResult.ARRIVED
              or row.get('final_joint_error', 1.0) > JOINT_TOLERANCE):
            return False
    return len(rows) == len(steps)


def write_profile_comparison(report_dir: str, arm: ArmModel) -> list[str]:
    """
    Write one plot per profile family and a table (appended to metrics.md); return the files.

    Offline, on the Mover6 report's linear example: 20 waypoints from home to (0.445, 0, 0.4425)
    with the home orientation, planned as the planner does, timed by every controller profile.
    """
    from mover6_control.control.profiles import PROFILE_FAMILIES
    from mover6_control.kinematics.forward import fk
    from mover6_control.planning.planner_core import plan_pose_goal
    from mover6_control.tools import plots
    q_home = np.zeros(arm.n_joints)
    T_goal = fk(arm, q_home).copy()
    T_goal[:3, 3] = (0.445, 0.0, 0.4425)
    waypoints = plan_pose_goal(arm, q_home, T_goal, 'linear').q
    files, lines = [], [
        '', "Every profile on the Mover6 report's linear example (offline plan, 1 ms samples):",
        '',
        '| family | profile | duration [s] | peak speed [rad/s] | peak acceleration [rad/s^2] | '
        'peak jerk [rad/s^3] | path deviation [mm] |', '|---|---|---|---|---|---|---|']
    for family, names in PROFILE_FAMILIES.items():
        rows = [plots.profile_metrics(arm, name, q_home, waypoints) for name in names]
        slug = family.replace(' ', '_')
        files.append(plots.plot_profile_comparison(
            rows, os.path.join(report_dir, f'profiles_{slug}.png'),
            f"{family}: the Mover6 report's linear example"))
        lines += [f'| {family} | {r["profile"]} | {r["duration"]:.2f} | {r["peak_speed"]:.3f} | '
                  f'{r["peak_acceleration"]:.3f} | {r["peak_jerk"]:.1f} | '
                  f'{r["deviation"] * 1e3:.2f} |' for r in rows]
    with open(os.path.join(report_dir, 'metrics.md'), 'a') as f:
        f.write('\n'.join(lines) + '\n')
    return files


def main(argv: Optional[list[str]] = None) -> int:
    """Run the showcase; exit 0 only when everything behaved."""
    parser = argparse.ArgumentParser(prog='demo', description=__doc__.split('\n\n')[0])
    parser.add_argument('--report', default=os.path.join(os.getcwd(), 'report'),
                        help='folder for plots, animation and metrics (default ./report)')
    parser.add_argument('--quick', action='store_true',
                        help="only the Mover6 report's linear example and a refused goal")
    parser.add_argument('--no-render', action='store_true', help='skip the animation')
    parser.add_argument('--record', default=None,
                        help='the recording (rosbag2 MCAP folder, must not exist; default '
                             'REPORT/rosbag2_<date>-<time>): the report is made from it')
    parser.add_argument('--no-record', action='store_true',
                        help='no recording: the report is made from what the demo saw')
    parser.add_argument('--hardware', default='sim', choices=STACKS,
                        help='the arm: sim (the MuJoCo bridge, default) or can-sim (the '
                        'driver on the CAN-level Mover6, over a pty)')
    parser.add_argument('--jog-units', default='rad_per_s', choices=JOG_UNITS,
                        help="the controller's /JointJog units: rad_per_s (default) or "
                        "fraction_of_max (the vendor driver's; the sim, or the driver, acts on "
                        'them)')
    args = parser.parse_args(argv)
    showcase = CAN_SHOWCASE if args.hardware == 'can-sim' else SHOWCASE
    steps = (showcase[0], showcase[-2]) if args.quick else showcase
    report_dir = os.path.abspath(args.report)
    bag = None
    try:    # a recording path that cannot be written stops the demo before anything starts
        if args.record and not args.no_record:
            bag = check_bag_path(args.record)
        os.makedirs(os.path.join(report_dir, 'logs'), exist_ok=True)
        if not args.record and not args.no_record:
            bag = check_bag_path(os.path.join(report_dir, default_path()))
    except InvalidInputError as err:
        print(f'demo: {err}; nothing started', file=sys.stderr)
        return 2
    env = dict(os.environ)
    local_dds.apply_default(env)   # the launchers' DDS: loopback only

    def say(text):
        print(text, flush=True)

    t_start = time.monotonic()
    say(f'starting {STACKS[args.hardware]}, controller and planner (ROS_DOMAIN_ID='
        f'{env.get("ROS_DOMAIN_ID", "0")}, logs in {report_dir}/logs)')
    bag_recorder = None
    if bag:
        say(f'recording into {bag}')
        bag_recorder = start_recorder(bag, os.path.join(report_dir, 'logs'), env)
    stack = start_stack(os.path.join(report_dir, 'logs'), env, args.hardware, args.jog_units)
    rows = []
    contacts = None
    arm = mover6(LIMIT_SET[args.hardware])
    rclpy.init()
    client = GoalClient(name='demo')
    try:
        recorder = Recorder(client, arm.joint_names)
        problem = client.wait_ready(timeout=60.0)
        if problem:
            say(f'RESULT failed: {problem} (see {report_dir}/logs)')
            return 1
        for step in steps:
            rows.append(run_step(client, recorder, arm, step, say))
        client.spin_until(lambda: False, 0.2)      # the last contact report
        contacts = recorder.contacts
    finally:
        client.destroy_node()
        rclpy.try_shutdown()
        if bag_recorder is not None:
            stop_stack(bag_recorder)   # first: the file is finished while the nodes still run
        stop_stack(stack)
    if bag and os.path.isfile(os.path.join(bag, 'metadata.yaml')):
        say(f'report from the recording {bag} ({bag_size(bag) / 1e6:.2f} MB)')
        _, files = make_report(bag, report_dir, arm, render=not args.no_render, say=say)
    else:
        if bag:
            say(f'the recording {bag} was not finished (see logs/recorder.log): the report is '
                'made from what the demo saw')
        files = write_files(report_dir, rows, arm, render=not args.no_render)
    files += write_profile_comparison(report_dir, arm)
    ok = passed(rows, steps)
    if args.hardware != 'sim':
        say('simulator contacts: not reported through the driver (the CAN-level arm has no '
            'topic of its own)')
    elif contacts is None:
        say('simulator contacts: no report (a sim_bridge without /sim_bridge/contacts)')
    else:
        touched = contacts.get('contact_steps', '0') != '0'
        say('simulator contacts: ' + (f'the arm touched: {contacts.get("first_contact")}'
                                      if touched else 'none: no motion touched anything'))
        ok = ok and not touched
    with open(os.path.join(report_dir, 'metrics.md')) as f:
        say('\n' + f.read())
    say(f'report: {report_dir} ({len(files)} files)')
    say(f'DEMO {"PASSED" if ok else "FAILED"} in {time.monotonic() - t_start:.1f} s')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
