"""Benchmarks of mover6_control: run all with ``./run.sh bench`` (python -m bench)."""
