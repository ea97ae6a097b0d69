"""Benchmarks: ``pneunet-grasp bench speed`` and ``pneunet-grasp bench solvers``."""
