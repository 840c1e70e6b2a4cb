"""Packaging of swarm_eval (ament_python): everything is declared in setup.cfg."""

from setuptools import setup

setup()
