"""Packaging of swarm_sim (ament_python)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'swarm_sim'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config',
         glob('config/*.yaml') + glob('config/*.json') + glob('config/*.rviz')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Swarm Formation Engineering',
    maintainer_email='engineering@swarm-formation.dev',
    description='pybullet world, sensors and radio medium of the swarm, and the sim node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_node = swarm_sim.sim_node:main',
            'monitor_node = swarm_sim.monitor_node:main',
            'live_view_node = swarm_sim.live_view_node:main',
        ],
    },
)
