"""Imported first by the fork server of ``swarm_agent.prefork``: the server dies with the
launcher that started it (``prefork.guard_fork_server``). Importing it anywhere else does
nothing: the guard acts only in a direct child of the process named in its environment."""

from swarm_agent.prefork import guard_fork_server

guard_fork_server()
