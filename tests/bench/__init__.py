"""Benchmarks and the speech-model trainer: the repository's, never in the wheel.

Run them from a checkout with ``python -m tests.bench NAME`` (``--help`` lists them). Each
``bench_NAME`` module has ``main(quick)``, which prints its figures as JSON lines and returns them,
and ``missed(results)``, which names what missed its target. The files are not named ``test_*``:
pytest never collects them; the tests that run a bench with ``--quick`` are tests/test_bench_*.py.
"""
