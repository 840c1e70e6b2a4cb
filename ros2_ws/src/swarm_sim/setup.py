"""Packaging of swarm_sim (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
