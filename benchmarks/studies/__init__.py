"""Studies: one-off runnable investigations (``python -m benchmarks.studies.<name>``).

Each writes its own report under ``benchmarks/results/<name>/`` (or one file there) and has a
decision record in ``docs/studies/``. Nothing here is imported by the benchmark engine
(:mod:`benchmarks.runner`) or by the library (``gp_agents``, ``gp_envs``) when they are
imported; the one exception is :mod:`benchmarks.studies.variants`, the study variants of the
controller registry, which :func:`benchmarks.controllers.load_study_variants` imports the first
time a study variant is asked for.
"""
