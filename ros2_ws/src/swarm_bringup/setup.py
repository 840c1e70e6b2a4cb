"""Packaging of swarm_bringup (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
