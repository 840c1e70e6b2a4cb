"""Packaging of swarm_mission (ament_python)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'swarm_mission'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        ('share/' + PACKAGE + '/shapes', glob('shapes/*.json') + glob('shapes/*.svg')
         + glob('shapes/*.png')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Swarm Formation Engineering',
    maintainer_email='engineering@swarm-formation.dev',
    description='Formation shapes, bubble packing and fractal partitioning, and the mission node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'mission_node = swarm_mission.mission_node:main',
        ],
    },
)
