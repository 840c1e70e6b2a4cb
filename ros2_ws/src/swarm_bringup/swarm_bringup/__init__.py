"""Bring-up of the swarm: launch plan, launcher, supervisor of a run, HIL demo.

One launch source: ``launch_plan`` describes a run's processes as data; the launcher
(``scripts/launch_swarm.py``, ``ros2 run swarm_bringup launch_swarm``) starts them as
child processes and ``launch/swarm.launch.py`` renders them through launch_ros.
"""
