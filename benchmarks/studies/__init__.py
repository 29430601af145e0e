"""Studies: one-off runnable investigations (``python -m benchmarks.studies.<name>``).

Each writes its own report under ``benchmarks/results/<name>/``. Nothing here is imported by the
benchmark engine (:mod:`benchmarks.runner`) or by the library (``gp_agents``, ``gp_envs``).
"""
