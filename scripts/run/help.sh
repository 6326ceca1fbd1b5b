# shellcheck shell=bash
# ./run.sh help: what the entry point does (sourced by run.sh).

usage() {
    cat <<'EOF'
mover6_control: the one entry point.

  ./run.sh demo            start the nodes headless, run the showcase (recorded), print the results
  ./run.sh test            colcon build + colcon test (pytest summary on the console)
                           (inside a private network namespace when the machine allows one)
  ./run.sh launch [args]   the stack (the arm or its driver, controller, planner, state
                           publisher, markers) in the foreground until Ctrl-C (scripts/launch.sh;
                           --help lists the options)
  ./run.sh goal ...        the goal CLI (./run.sh goal --help)
  ./run.sh console [--port P]  the web console on http://127.0.0.1:8080 (docs/console.md)
  ./run.sh record [-o BAG] [TOPICS]  record the stack's topics (rosbag2 MCAP) until Ctrl-C
  ./run.sh report BAG      the demo's report (plots, metrics, gif) of a recording
  ./run.sh first-run [--can-sim] [--yes]  each joint +5 deg and back, its direction confirmed,
                           the calibration file written (docs/real_arm.md)
  ./run.sh bench [--quick] the benchmarks: tables on the console, JSON in bench/results/
  ./run.sh generate [--check]  write config/<node>.yaml and docs/parameters.md from the
                           parameter table (mover6_control/parameters.py)
  ./run.sh setup           only set up, with the browser of the console's test (the rest is
                           also done on first use of any other command)
  ./run.sh exec CMD ...    run CMD inside the project environment

On a machine with a sourced ROS 2 Jazzy install it uses that install. Otherwise it makes a
project-local virtual environment (.venv) with ROS 2 Jazzy from PyPI wheels (these need
Python 3.11), builds a local control_msgs (JointJog, FollowJointTrajectory) and tf2_msgs
(TFMessage) when none is found, and builds this package with colcon into .colcon/. What it installs is listed in requirements/*.txt.
Re-running is quick and changes nothing. It works from any directory.

Environment: PYTHON  the interpreter that makes the venv (default python3)
             MOVER6_VENV, MOVER6_WS  the venv and the colcon workspace (default .venv, .colcon)
DDS: this machine only (UDP on 127.0.0.1, config/fastdds_local.xml) unless you set your own
             (ROS_AUTOMATIC_DISCOVERY_RANGE, FASTRTPS_DEFAULT_PROFILES_FILE, ...): docs/dds.md.
EOF
}
