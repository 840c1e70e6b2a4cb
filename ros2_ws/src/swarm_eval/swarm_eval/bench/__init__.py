"""The benchmark suite (``benchmarks/run_all.py``, ``ros2 run swarm_eval benchmarks``):
in-process sections (``sections``), sections run in child processes (``processes``), the
issue's targets and the markdown report (``report``), the command line (``suite``).

It is its own small harness rather than pytest-benchmark: most of its figures are not
timings of a callable (DSDV convergence in simulated seconds, real-time factors, CPU
cores and memory of child processes and ROS runs), they are compared across swarm sizes
against the issues' targets and merged section by section into docs/benchmarks.json;
the timings it does take are medians of a few calls of work that lasts up to seconds
at 1000 agents, where pytest-benchmark's calibrated rounds would multiply the run time.
"""
