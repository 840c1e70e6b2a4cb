"""The benchmark suite (``benchmarks/run_all.py``, ``ros2 run swarm_eval benchmarks``):
in-process sections (``sections``), sections run in child processes (``processes``), the
issue's targets and the markdown report (``report``), the command line (``suite``)."""
