"""Packaging of swarm_bridge (ament_python)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'swarm_bridge'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Swarm Formation Engineering',
    maintainer_email='engineering@swarm-formation.dev',
    description='XBee bridge to PIC16F690 omni-wheel robots, and a board emulator.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'bridge_node = swarm_bridge.bridge_node:main',
            'robot_emulator = swarm_bridge.emulator:main',
            'hil_world_node = swarm_bridge.hil_world_node:main',
            'hw_agent_node = swarm_bridge.hw_agent_node:main',
            'camera_tracker_node = swarm_bridge.camera_tracker_node:main',
            'camera_calibrate = swarm_bridge.camera_calibrate:main',
        ],
    },
)
