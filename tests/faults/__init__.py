"""The fault-injection suite's cases (:mod:`.cases`, :mod:`.hazards`) and its runner and
checker (:mod:`.suite`): run by ``tests/test_faults_suite.py`` and, outside pytest, by
``experiments/fault_suite.py``."""
