"""The benchmark: the top layer of swiptopt, and the only part of it that imports ``rl`` and
``planners``.

- :mod:`~swiptopt.benchmark.algorithms`: the registry of algorithms a benchmark can run;
- :mod:`~swiptopt.benchmark.experiment`: experiments (TOML) and the built-in ones;
- :mod:`~swiptopt.benchmark.runner`: tasks on local worker processes or a Dask cluster;
- :mod:`~swiptopt.benchmark.store`: the crash-safe SQLite results store;
- :mod:`~swiptopt.benchmark.tables`, :mod:`~swiptopt.benchmark.plots`: tables and figures;

``swiptopt.cli`` is its command line. Nothing here is imported by ``import swiptopt``.
"""
