"""
The reference says how things are now: no history in docstrings, comments or pages.

A docstring, a comment or a page of docs/ (and the README) that names an issue of this project
("issue 32"), a round of work ("round 4") or says "as before" tells the reader about the work,
not the code; that belongs in the commit messages and, for dated measurements,
bench/HISTORY.md (not checked here). A backticked name in a page (`Class.method`,
`module.function`) must exist in the code: a renamed function leaves a page that points at
nothing.
"""

import ast
import glob
import io
import os
import re
import tokenize

from source_tree import ROOT

PACKAGES = ('mover6_control', 'sim_bridge', 'bench')
HISTORY = [
    (re.compile(r'\bissues?\s+#?\d+', re.I), 'an issue number'),
    (re.compile(r'\bround\s+\d+\b', re.I), 'a round'),
    (re.compile(r'\b(first|second|third|fourth|fifth|last|this)\s+round\b', re.I), 'a round'),
    (re.compile(r'\bas before\b', re.I), '"as before"'),
    (re.compile(r'\bbefore this (change|round|pass|issue)\b', re.I), '"before this ..."'),
]
# An upstream project's issue ('eProsima/Fast-DDS issue 6535') is a reference, not our history.
UPSTREAM = re.compile(r'[\w.-]+/[\w.-]+\s+$')


def python_files():
    """Return every Python file of the product's packages."""
    out = []
    for package in PACKAGES:
        out += glob.glob(os.path.join(ROOT, package, '**', '*.py'), recursive=True)
    return sorted(out)


def doc_pages():
    """Return the README and every page of docs/."""
    return [os.path.join(ROOT, 'README.md')] + sorted(
        glob.glob(os.path.join(ROOT, 'docs', '*.md')))


def prose_of(path):
    """Return (line, text) of every docstring and comment of a Python file."""
    with open(path) as f:
        source = f.read()
    out = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            out.append((token.start[0], token.string))
    for node in ast.walk(ast.parse(source, path)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(
                    body[0].value, ast.Constant) and isinstance(body[0].value.value, str):
                out.append((body[0].lineno, body[0].value.value))
    return out


def history_in(text):
    """Return what of the history patterns ``text`` holds (empty when none)."""
    flat = ' '.join(text.split())
    found = []
    for pattern, what in HISTORY:
        for match in pattern.finditer(flat):
            if what == 'an issue number' and UPSTREAM.search(flat[:match.start()]):
                continue
            found.append(f'{what}: {match.group(0)!r}' if what[0] != '"' else what)
    return found


def test_the_patterns_find_history_and_pass_references():
    assert history_in('as measured in issue 32, round 4') == [
        "an issue number: 'issue 32'", "a round: 'round 4'"]
    assert history_in('served as before') == ['"as before"']
    assert history_in('a stall (eProsima/Fast-DDS issue 6535)') == []
    assert history_in('the steps between run in the same round') == []


def test_no_history_in_docstrings_and_comments():
    found = []
    for path in python_files():
        for line, text in prose_of(path):
            found += [f'{os.path.relpath(path, ROOT)}:{line}: {h}' for h in history_in(text)]
    assert found == []


def test_no_history_in_the_pages():
    found = []
    for path in doc_pages():
        with open(path) as f:
            for number, line in enumerate(f, 1):
                found += [f'{os.path.relpath(path, ROOT)}:{number}: {h}'
                          for h in history_in(line)]
    assert found == []


# --- backticked names in the pages ---------------------------------------------------------

# Words in backticks that are no Python name of ours: message fields, other programs' names and
# options, shell variables, file formats. A topic, path, command or value with a space, a slash
# or a character a Python name has not is not looked up at all.
NOT_CODE = {
    # ROS message fields and rclpy / ROS names
    'frame_id', 'time_from_start', 'header', 'stamp', 'position', 'velocity', 'effort',
    'joint_names', 'points', 'velocities', 'displacements', 'duration', 'success', 'message',
    'raw', 'use_sim_time', 'respawn', 'spin_once', 'EventsExecutor', 'SingleThreadedExecutor',
    'MultiThreadedExecutor', 'ParameterDescriptor', 'JointTrajectoryPoint', 'Publisher.publish',
    'Clock.now', 'Clock.sleep_until', 'ClockEvent', 'Time', 'serialize_message',
    'deserialize_message', 'robot_state_publisher', 'rviz2', 'ros2_control', 'rosbag2',
    'change_state', 'PENDING', 'ACTIVE', 'REJECTED', 'RECALLED', 'SUCCEEDED', 'ABORTED',
    'CANCELED', 'OK', 'WARN', 'ERROR', 'STALE', 'GoalStatus', 'JointJog', 'JointState',
    'PoseStamped', 'PoseArray', 'TwistStamped', 'Float32MultiArray', 'DiagnosticStatus',
    'FollowJointTrajectory', 'Trigger', 'SetBool', 'GripperCommand', 'MultiArrayLayout',
    # other libraries
    'ParametrizeConstAccel', 'qpos', 'mj_step', 'mj_forward', 'viewer.sync', 'nogil',
    'fastmath', 'atan2', 'acos', 'sin', 'cos', 'numba', 'numpy', 'scipy', 'toppra', 'ikpy',
    'ruckig', 'mujoco', 'viser', 'pyserial', 'python-can', 'selenium', 'least_squares',
    'socketcan', 'slcan', 'can0', 'vcan0', 'pytest', 'colcon', 'pip', 'xacro', 'udev',
    'SCHED_FIFO', 'SCHED_OTHER', 'CAP_SYS_NICE', 'rtprio', 'OpenBLAS', 'MCAP', 'mcap',
    'panda_moveit_config', 'moveit_resources', 'dialout', 'tform2rotm', 'CPRMover6.cpp',
    'referencing_required', 'referencing_priority',
    'gc.callbacks', 'array.array', 'time.sleep', 'time.time_ns', 'struct', 'RLock', 'Event',
    # environment variables and DDS settings
    'ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS',
    'RMW_IMPLEMENTATION', 'FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_BUILTIN_TRANSPORTS',
    'OPENBLAS_NUM_THREADS', 'LOCALHOST', 'SUBNET', 'SYSTEM_DEFAULT', 'UDPv4', 'SHM',
    'MOVER6_WS', 'MOVER6_DDS', 'MOVER6_TICK_WATCHDOG', 'PYTHONPATH', 'DISPLAY',
}
# Other libraries' names: `np.asarray(pose)`, `scipy.spatial` are theirs.
LIBRARIES = {'np', 'numpy', 'scipy', 'mujoco', 'rclpy', 'launch', 'launch_ros', 'toppra', 'ikpy',
             'can', 'serial', 'ruckig', 'viser', 'selenium', 'os', 'sys', 'time', 'threading'}
FILE_ENDINGS = {'py', 'md', 'yaml', 'json', 'sh', 'urdf', 'srdf', 'xml', 'txt', 'gif', 'png',
                'jpg', 'csv', 'mcap', 'db3', 'cpp', 'h', 'rules', 'launch', 'xacro', 'stl', 'dae',
                'rviz'}
NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*(\(.*\))?$')
# `kinematics/reachability.check_pose`: a module by its folder, then a name in it.
IN_FOLDER = re.compile(r'^(?:[A-Za-z_]\w*/)+([A-Za-z_]\w*(\.[A-Za-z_]\w*)+)(\(.*\))?$')


class CodeNames:
    """Every name the code defines, by ast: modules, classes with their members, functions."""

    def __init__(self, packages):
        self.modules = {}          # module name (last part) -> set of its top-level names
        self.classes = {}          # class name -> set of its members
        self.names = set()         # every defined name and string constant that is a name
        for package in packages:
            for path in glob.glob(os.path.join(ROOT, package, '**', '*.py'), recursive=True):
                self.read(path)

    def read(self, path):
        """Add the names of one module."""
        with open(path) as f:
            tree = ast.parse(f.read(), path)
        rel = os.path.relpath(path, ROOT)[:-3].split(os.sep)
        parts = rel[:-1] if rel[-1] == '__init__' else rel
        self.names.update(parts)
        top = self.modules.setdefault(parts[-1], set())
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                members = self.classes.setdefault(node.name, set())
                for item in ast.walk(node):
                    members.update(self.defined(item))
                    if isinstance(item, ast.Attribute) and isinstance(item.ctx, ast.Store):
                        members.add(item.attr)
            for name in self.defined(node):
                self.names.add(name)
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                self.names.update(w for w in re.split(r'[\s/~,.]+', node.value)
                                  if re.match(r'^[A-Za-z_]\w*$', w))
            if isinstance(node, ast.Attribute):
                self.names.add(node.attr)
        for node in tree.body:
            top.update(self.defined(node))
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                top.update((a.asname or a.name).split('.')[0] for a in node.names)

    @staticmethod
    def defined(node):
        """Return the names ``node`` defines (a class, a function, an assignment's targets)."""
        if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            return {node.name}
        if isinstance(node, ast.Assign):
            return {t.id for t in node.targets if isinstance(t, ast.Name)}
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            return {node.target.id}
        if isinstance(node, ast.arg):
            return {node.arg}
        return set()

    def problem(self, span):
        """Return why the backticked ``span`` names nothing in the code, or None."""
        folder = IN_FOLDER.match(span)
        if folder:
            span = folder.group(1)
        if span in NOT_CODE or not NAME.match(span):
            return None
        dotted = span.split('(')[0]
        if dotted in NOT_CODE:
            return None
        parts = dotted.split('.')
        if parts[-1] in FILE_ENDINGS or parts[0] in LIBRARIES:
            return None                 # a file name (the file check's), another library's
        if folder and parts[0] not in self.modules:
            return f'no module {parts[0]!r}'
        for part in parts:
            if part not in self.names and part not in NOT_CODE:
                return f'{part!r} is defined nowhere'
        for owner, member in zip(parts, parts[1:]):
            if owner in self.classes and owner not in self.modules:
                if member not in self.classes[owner]:
                    return f'class {owner} has no {member!r}'
            elif owner in self.modules and owner not in self.classes:
                if member not in self.modules[owner] and member not in self.classes:
                    return f'module {owner} has no {member!r}'
        return None


def backticked(path):
    """Return (line, span) of every backticked span of a page, outside fenced code blocks."""
    out, fenced = [], False
    with open(path) as f:
        for number, line in enumerate(f, 1):
            if line.lstrip().startswith('```'):
                fenced = not fenced
                continue
            if not fenced:
                out += [(number, span) for span in re.findall(r'`([^`\n]+)`', line)]
    return out


def test_the_resolver_finds_a_name_that_is_not_there():
    names = CodeNames(PACKAGES)
    assert names.problem('ControllerCore.prepare_demand') is None
    assert names.problem('conversions.pose_goal_from_msg') is None
    assert names.problem('ControllerCore.no_such_member') is not None
    assert names.problem('conversions.no_such_function') is not None
    assert names.problem('no_such_module_or_name') is not None
    assert names.problem('kinematics/reachability.check_pose') is None
    assert names.problem('kinematics/reachability.no_such_function') is not None
    assert names.problem('/joint_states') is None and names.problem('./run.sh bench') is None


def test_backticked_names_in_the_pages_exist():
    names = CodeNames(PACKAGES + ('bench', 'test', 'launch'))
    found = []
    for path in doc_pages():
        if os.path.basename(path) == 'parameters.md':
            continue    # generated from the parameter table: its spans are parameter names
        for number, span in backticked(path):
            why = names.problem(span)
            if why:
                found.append(f'{os.path.relpath(path, ROOT)}:{number}: `{span}`: {why}')
    assert found == []


def test_backticked_files_exist():
    """A backticked path of a Python file (`nodes/planner/node.py`) is a file of the tree."""
    files = {os.path.relpath(p, ROOT).replace(os.sep, '/')
             for p in glob.glob(os.path.join(ROOT, '**', '*.py'), recursive=True)
             if '.venv' not in p and '.colcon' not in p}
    found = []
    for path in doc_pages():
        for number, span in backticked(path):
            if not re.match(r'^[\w./-]+\.py$', span) or '/' not in span:
                continue
            tail = span.lstrip('./')
            if not any(f == tail or f.endswith('/' + tail) for f in files):
                found.append(f'{os.path.relpath(path, ROOT)}:{number}: `{span}`')
    assert found == []
