"""Packaging of swarm_agent (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
