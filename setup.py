"""Install the mover6_control ament_python package."""

from glob import glob
import os
import runpy

from setuptools import find_packages, setup

package_name = 'mover6_control'
# The executables and their modules: one table, read without importing the package.
EXECUTABLES = runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                          package_name, 'resources.py'))['EXECUTABLES']

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
        (os.path.join('share', package_name, 'meshes'), glob('meshes/*')),
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
        'console_scripts': [f'{name} = {module}:main'
                            for name, module in EXECUTABLES.items()],
    },
)
