"""Evaluation of the swarm (thesis chapter 4): the headless Monte Carlo evaluator
(``evaluate``), the studies (faults, methods, meshes, shapes, localization), the LQR
report and the benchmark suite (``bench``). Each has a ``main(argv)``, a console script
of this package and a thin wrapper in the repository's scripts/ or benchmarks/."""
