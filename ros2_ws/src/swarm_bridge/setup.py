"""Packaging of swarm_bridge (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
