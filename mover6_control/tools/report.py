"""
The demo's report made from a recording: ``./run.sh report BAG [--report DIR]``.

Reads a rosbag2 MCAP recording (``./run.sh record``, the demo's own, or the real arm's) with
``mcap_ros2`` from the message definitions embedded in it (no ROS needed) and rebuilds each
motion from what went over the wire: a goal (/pose_goal, /path_goal or a shape topic), the
planner's answer (/planner/status: planned, or refused with its reason), the demand of that goal
(/joint_demands), the controller's result for it (/controller/status) and the measured
/joint_states in between. Writes what the demo writes: per motion the planned vs realised tool
path, the joint trajectories with limits, the velocities; metrics.md / metrics.json; and
motion.gif (the arm rendered offscreen) unless ``--no-render``.
"""

import argparse
import glob
import json
import os
import sys
from typing import Any, Callable, Optional, Sequence

from mover6_control.control.status import FINAL_RESULTS, MotionResult, PlannerResult, State
from mover6_control.errors import InvalidInputError
from mover6_control.kinematics.arm import ArmModel, LIMIT_SETS, mover6
from mover6_control.kinematics.forward import fk, fk_batch
from mover6_control.kinematics.rotations import pose_error
from mover6_control.motion.metrics import max_deviation_from_polyline
from mover6_control.nodes.messages.conversions import pose_from_msg
from mover6_control.nodes.messages.demand_messages import demand_id_from_msg, demands_from_msg
from mover6_control.tools.goal_convention import format_numbers, goal_from_pose
import numpy as np
import yaml

POSE_SHAPES = ('linear', 'parabolic', 'joint')
PATH_SHAPES = ('spline', 'arc', 'parabolic', 'joint')
DEFAULT_SHAPE = {'pose_goal': 'linear', 'path_goal': 'spline'}   # the planner's defaults

# A message as mcap_ros2 decodes it: a class it makes from the embedded definition (no ROS).
Message = Any
Recorded = list[tuple[float, Message]]          # (receive time [s], message), in that order
Topics = dict[str, Recorded]                    # topic name without namespace -> messages
ParameterChange = tuple[float, str, str]        # (t [s], parameter name, new value)
Goal = tuple[float, str, str, np.ndarray]       # (t [s], kind, shape, poses (k, 4, 4))


def mcap_file(bag: str) -> str:
    """Return the .mcap file of recording ``bag`` (its folder, or the file itself)."""
    if os.path.isfile(bag):
        return bag
    meta = os.path.join(bag, 'metadata.yaml')
    if os.path.isfile(meta):
        with open(meta) as f:
            info = yaml.safe_load(f)['rosbag2_bagfile_information']
        return os.path.join(bag, info['relative_file_paths'][0])
    found = sorted(glob.glob(os.path.join(bag, '*.mcap')))
    if not found:
        raise InvalidInputError(f'no recording at {bag} (no metadata.yaml, no .mcap file)')
    return found[0]


def read_recording(bag: str) -> tuple[Topics, dict[str, int]]:
    """
    Return ``{topic: [(t [s], message)]}`` of a recording, in receive order, and its counts.

    Topic names lose their namespace: the one of the topic that ends in ``joint_states``.
    """
    from mcap_ros2.reader import read_ros2_messages
    path = mcap_file(bag)
    raw = {}
    for m in read_ros2_messages(path):
        raw.setdefault(m.channel.topic, []).append((m.log_time_ns * 1e-9, m.ros_msg))
    states = [t for t in raw if t.endswith('/joint_states')]
    namespace = states[0][:-len('joint_states')] if states else '/'
    topics = {}
    for topic, items in raw.items():
        name = topic[len(namespace):] if topic.startswith(namespace) else topic.lstrip('/')
        topics[name] = items
    return topics, {t: len(v) for t, v in raw.items()}


def values(status: Message) -> dict[str, str]:
    """Return the key -> value dict of a DiagnosticStatus."""
    return {kv.key: kv.value for kv in status.values}


def goal_shape(topic: str, t: float,
               parameter_changes: Sequence[ParameterChange]) -> tuple[str, str]:
    """Return the shape of a goal: its topic's, else the planner's parameter at time ``t``."""
    base, _, shape = topic.partition('/')
    if shape:
        return base, shape
    key = 'motion' if base == 'pose_goal' else 'path_motion'
    value = DEFAULT_SHAPE[base]
    for t_change, name, new in parameter_changes:
        if t_change <= t and name == key:
            value = new
    return base, value


def planner_parameter_changes(topics: Topics) -> list[ParameterChange]:
    """Return ``[(t, name, value)]`` of the planner's parameter changes (/parameter_events)."""
    out = []
    for t, event in topics.get('parameter_events', []):
        if not event.node.endswith('/planner'):
            continue
        for p in list(event.new_parameters) + list(event.changed_parameters):
            if p.name in ('motion', 'path_motion') and p.value.type == 4:    # a string
                out.append((t, p.name, p.value.string_value))
    return out


def goals(topics: Topics, parameter_changes: Sequence[ParameterChange]) -> list[Goal]:
    """Return ``[(t, kind, shape, poses (k, 4, 4))]`` of every goal, in time order."""
    out = []
    for topic, items in topics.items():
        base = topic.partition('/')[0]
        shapes = POSE_SHAPES if base == 'pose_goal' else PATH_SHAPES
        if base not in DEFAULT_SHAPE or (topic != base and topic.partition('/')[2] not in shapes):
            continue
        for t, msg in items:
            poses = ([pose_from_msg(msg.pose).matrix] if base == 'pose_goal'
                     else [pose_from_msg(p).matrix for p in msg.poses])
            if poses:
                out.append((t, *goal_shape(topic, t, parameter_changes), np.array(poses)))
    return sorted(out, key=lambda g: g[0])


def joint_samples(topics: Topics,
                  names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (t (m,), q (m, 6), qd (m, 6)) of /joint_states mapped by name."""
    t, q, qd = [], [], []
    for stamp, msg in topics.get('joint_states', []):
        index = {n: i for i, n in enumerate(msg.name)}
        try:
            q.append([msg.position[index[n]] for n in names])
            qd.append([msg.velocity[index[n]] if len(msg.velocity) else 0.0 for n in names])
            t.append(stamp)
        except (KeyError, IndexError):
            continue
    return np.array(t), np.array(q).reshape(-1, len(names)), np.array(qd).reshape(-1, len(names))


def first(items: Recorded, t0: float, t1: float,
          predicate: Callable[[Message], bool]) -> Optional[tuple[float, Message]]:
    """Return the first ``(t, msg)`` of ``items`` in [t0, t1) for which ``predicate(msg)``."""
    return next(((t, m) for t, m in items if t0 <= t < t1 and predicate(m)), None)


def motion_rows(topics: Topics, arm: ArmModel) -> list[dict]:
    """Return one metrics row per goal of the recording (as the demo's ``run_step`` makes)."""
    changes = planner_parameter_changes(topics)
    all_goals = goals(topics, changes)
    t_js, q_js, qd_js = joint_samples(topics, arm.joint_names)
    planner = topics.get('planner/status', [])
    controller = topics.get('controller/status', [])
    demands = topics.get('joint_demands', [])
    rows = []
    answered = (PlannerResult.PLANNED, PlannerResult.REFUSED, PlannerResult.FAILED)
    for k, (t_goal, kind, shape, poses) in enumerate(all_goals):
        t_next = all_goals[k + 1][0] if k + 1 < len(all_goals) else np.inf
        T_goal = poses[-1]
        row = {'motion': f'{k + 1:02d}_{kind}_{shape}',
               'goal': format_numbers(goal_from_pose(arm, T_goal))}
        answer = first(planner, t_goal, t_next, lambda m: values(m).get('result') in answered)
        if answer is None:
            rows.append(row | {'result': 'failed', 'reason': 'no planner answer recorded'})
            continue
        v = values(answer[1])
        if v.get('result') != PlannerResult.PLANNED:
            rows.append(row | {'result': 'refused' if v['result'] == PlannerResult.REFUSED
                               else 'failed', 'reason': v.get('reason', ''),
                               'message': answer[1].message})
            continue
        goal_id = v.get('goal_id', '')
        demand = first(demands, t_goal, t_next, lambda m: demand_id_from_msg(m) == goal_id)
        done = first(controller, t_goal, t_next,
                     lambda m: values(m).get('goal_id') == goal_id
                     and values(m).get('result') in FINAL_RESULTS)
        if demand is None or done is None:
            rows.append(row | {'result': 'failed',
                               'reason': 'no demand recorded' if demand is None
                               else 'no controller result recorded'})
            continue
        # 'arrived' comes inside the goal tolerance; the figures are of the pose it then holds.
        settled = first(controller, done[0], t_next,
                        lambda m: values(m).get('state') != State.SETTLING)
        t_end = settled[0] if settled else done[0]
        after = np.nonzero(t_js > t_end)[0]
        last = after[0] if len(after) else len(t_js) - 1
        mask = (t_js >= t_goal) & (t_js <= t_js[last])
        Q = demands_from_msg(demand[1], arm.n_joints)
        q_final = q_js[last]
        row.update({
            'result': values(done[1]).get('result', MotionResult.ARRIVED),
            'duration': float(t_end - t_goal),
            'final_joint_error': float(np.abs(q_final - Q[-1]).max()),
            'final_position_error': float(pose_error(fk(arm, q_final), T_goal)[0]),
            'samples': {'t': (t_js[mask] - t_goal).tolist(), 'q': q_js[mask].tolist(),
                        'qd': qd_js[mask].tolist()}})
        planned = fk_batch(arm, Q)[:, :3, 3]
        row['planned_path'] = planned.tolist()
        if mask.any():
            row['max_path_deviation'] = float(max_deviation_from_polyline(
                fk_batch(arm, q_js[mask])[:, :3, 3], planned))
        rows.append(row)
    return rows


def write_report(report_dir: str, rows: list[dict], arm: ArmModel) -> list[str]:
    """Write metrics.json, metrics.md and the plots; return the list of files written."""
    from mover6_control.tools import plots
    files = []
    for row in rows:
        if 'samples' not in row or not row['samples']['t']:
            continue
        s = row['samples']
        t, q, qd = (np.asarray(s[k]) for k in ('t', 'q', 'qd'))
        realised = fk_batch(arm, q)[:, :3, 3]
        base = os.path.join(report_dir, row['motion'])
        files.append(plots.plot_path_3d(np.asarray(row['planned_path']), realised,
                                        base + '_path3d.png'))
        files.append(plots.plot_joint_trajectories(t, q, arm.lower, arm.upper,
                                                   base + '_joints.png'))
        files.append(plots.plot_joint_velocities(t, qd, arm.velocity_limits,
                                                 base + '_velocities.png'))
    table = [{k: v for k, v in row.items() if k not in ('samples', 'planned_path')}
             for row in rows]
    with open(os.path.join(report_dir, 'metrics.json'), 'w') as f:
        json.dump(table, f, indent=2)
    lines = ['| motion | goal X Y Z A B C (A B C from home) | result | duration [s] | '
             'final joint error [rad] | final tool position error [mm] | '
             'max deviation from planned path [mm] |',
             '|---|---|---|---|---|---|---|']
    for row in table:
        def num(key, scale=1.0, fmt='.4f'):
            return format(row[key] * scale, fmt) if key in row else '-'
        result = row['result'] + (f' ({row["reason"]})' if row['result'] == 'refused' else '')
        lines.append(f'| {row["motion"]} | {row.get("goal", "-")} | {result} | '
                     f'{num("duration", fmt=".2f")} | '
                     f'{num("final_joint_error")} | {num("final_position_error", 1e3, ".2f")} | '
                     f'{num("max_path_deviation", 1e3, ".2f")} |')
    with open(os.path.join(report_dir, 'metrics.md'), 'w') as f:
        f.write('\n'.join(lines) + '\n')
    files += [os.path.join(report_dir, 'metrics.json'), os.path.join(report_dir, 'metrics.md')]
    return files


def render_animation(report_dir: str, rows: list[dict], arm: ArmModel) -> Optional[str]:
    """Render the recorded motion of every step into one animated GIF; return its path."""
    if not os.environ.get('DISPLAY'):
        os.environ.setdefault('MUJOCO_GL', 'egl')   # read when MuJoCo is first imported
    from sim_bridge import render
    q = [np.asarray(r['samples']['q']) for r in rows if r.get('samples', {}).get('q')]
    t = [np.asarray(r['samples']['t']) for r in rows if r.get('samples', {}).get('q')]
    if not q:
        return None
    offset, times = 0.0, []
    for seg in t:
        times.append(seg + offset)
        offset = times[-1][-1] + 0.5
    return render.save_gif(arm, np.concatenate(times), np.concatenate(q),
                           os.path.join(report_dir, 'motion.gif'))


def write_files(report_dir: str, rows: list[dict], arm: ArmModel,
                render: bool = True) -> list[str]:
    """Write the metrics, the plots and (with ``render``) the animation; return the files."""
    files = write_report(report_dir, rows, arm)
    if render:
        gif = render_animation(report_dir, rows, arm)
        if gif:
            files.append(gif)
    return files


def make_report(bag: str, report_dir: str, arm: ArmModel, render: bool = True,
                say: Callable[[str], None] = print) -> tuple[list[dict], list[str]]:
    """Write the report of recording ``bag`` into ``report_dir``; return (rows, files)."""
    topics, counts = read_recording(bag)
    os.makedirs(report_dir, exist_ok=True)
    say(f'recording {bag}: ' + ', '.join(f'{t} {n}' for t, n in sorted(counts.items())))
    rows = motion_rows(topics, arm)
    return rows, write_files(report_dir, rows, arm, render)


def main(argv: Optional[list[str]] = None) -> int:
    """Make the report of a recording; exit 1 when it holds no motion."""
    parser = argparse.ArgumentParser(prog='report', description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', help='the recording: its folder (metadata.yaml) or .mcap file')
    parser.add_argument('--report', default=None,
                        help='folder for plots, animation and metrics (default BAG_report)')
    parser.add_argument('--limit-set', default='within_90_deg', choices=LIMIT_SETS,
                        help="joint limits drawn in the plots (the recorded stack's)")
    parser.add_argument('--no-render', action='store_true', help='skip the animation')
    args = parser.parse_args(argv)
    bag = os.path.abspath(args.bag)
    if not os.path.exists(bag):
        parser.error(f'no recording at {bag}')
    report_dir = os.path.abspath(args.report or bag.rstrip('/').removesuffix('.mcap') + '_report')
    try:
        rows, files = make_report(bag, report_dir, mover6(args.limit_set),
                                  render=not args.no_render)
    except InvalidInputError as err:
        print(f'report: {err}', file=sys.stderr)
        return 2
    with open(os.path.join(report_dir, 'metrics.md')) as f:
        print(f.read())
    print(f'report: {report_dir} ({len(files)} files, {len(rows)} motions)')
    return 0 if rows else 1


if __name__ == '__main__':
    sys.exit(main())
