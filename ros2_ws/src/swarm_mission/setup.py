"""Packaging of swarm_mission (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
