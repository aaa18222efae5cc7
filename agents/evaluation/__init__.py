"""Evaluating tuning policies: one episode, every policy on the same test flights of each
scenario (:mod:`~agents.evaluation.episodes`), the seed ranges (:mod:`~agents.evaluation.seeds`),
the statistics (:mod:`~agents.evaluation.statistics`) and the figure
(:mod:`~agents.evaluation.plots`).
"""
