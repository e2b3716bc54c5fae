"""Benchmarks, shipped with the package so that `botstage bench NAME` runs from any install.

Each ``bench_NAME`` module has ``main(quick)``, which prints its figures as JSON lines and returns
them, and ``missed(results)``, which names what missed its target. The files are not named
``test_*``: pytest never collects them.
"""
