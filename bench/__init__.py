"""Benchmarks and the report (``make demo`` = ``python -m bench.report``)."""
