"""Packaging of swarm_bringup (ament_python)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'swarm_bringup'

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
    description='Launch plan, launcher and launch file of the swarm, and the HIL demo.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'launch_swarm = swarm_bringup.supervisor_node:main',
            'hil_demo = swarm_bringup.hil_demo_node:main',
            'demo = swarm_bringup.demo:main',
            'recorder_node = swarm_bringup.recorder_node:main',
        ],
    },
)
