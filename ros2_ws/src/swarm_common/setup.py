"""Packaging of swarm_common (ament_python): what every swarm package shares."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'swarm_common'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Swarm Formation Engineering',
    maintainer_email='engineering@swarm-formation.dev',
    description='Robot types, fleets, shapes and goals, QoS, conversions and node helpers '
                'shared by every swarm package.',
    license='Apache-2.0',
)
