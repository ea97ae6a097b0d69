"""Benchmarks of the study layers: ``pneunet-grasp bench design`` (:mod:`~agents.bench.design`) and ``pneunet-grasp
bench train`` (:mod:`~agents.bench.train`). Figures, never a pass/fail.

The top layer with the commands: may import any package of ``agents``; none imports it.
"""
