"""Imported last by the fork server of ``swarm_agent.prefork``: compiles (or loads from
numba's cache) every kernel of the modules it imported (``swarm_common.jit.warm``), so
its children share the compiled code instead of each loading numba's compiler."""

from swarm_common.jit import warm

warm()
