"""Experiments: accuracy tables, noise sweeps, timing benchmarks and the HTML report."""
