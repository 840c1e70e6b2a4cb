"""Packaging of swarm_common (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
