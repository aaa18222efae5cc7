"""The learners compared on the same test flights: the statistics behind the learners' results
page (:mod:`~agents.comparison.statistics`).
"""
