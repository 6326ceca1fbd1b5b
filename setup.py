"""Install the mover6_control ament_python package."""

from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'mover6_control'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'),
         [path for path in glob('config/*') if os.path.isfile(path)]),
        (os.path.join('share', package_name, 'config', 'moveit'), glob('config/moveit/*')),
        (os.path.join('share', package_name, 'launch'), glob('launch/*.launch.py')),
        (os.path.join('share', package_name, 'scripts'), glob('scripts/*.sh')),
        (os.path.join('share', package_name, 'rviz'), glob('rviz/*.rviz')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='mover6_control developers',
    maintainer_email='dev@mover6-control.invalid',
    description='Pose-goal planner, JointJog controller and MuJoCo bridge for the Mover6 arm.',
    license='Apache-2.0',
    tests_require=['pytest', 'hypothesis'],
    entry_points={
        'console_scripts': [
            'planner = mover6_control.nodes.planner.node:main',
            'controller = mover6_control.nodes.controller.node:main',
            'sim_bridge = sim_bridge.bridge_node:main',
            'driver = mover6_control.nodes.driver.driver_node:main',
            'can_sim = sim_bridge.can_sim:main',
            'goal = mover6_control.tools.goal_cli:main',
            'teleop = mover6_control.tools.teleop:main',
            'state_publisher = mover6_control.nodes.state_publisher.node:main',
            'markers = mover6_control.nodes.markers.node:main',
            'recorder = mover6_control.nodes.recorder.node:main',
            'first_run = mover6_control.tools.first_run:main',
            'console = mover6_control.nodes.console.console_node:main',
        ],
    },
)
