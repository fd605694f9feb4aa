"""Benchmarks are run on their own: ``python -m pytest benchmarks/bench_*.py --benchmark-enable``.

They print the figures the README quotes; they never assert wall-clock targets (machines here
are shared and noisy)."""
