"""The scripts behind the documented numbers: thin ``main(argv)`` command lines over library
code, each with ``--help`` and a ``--quick`` mode the tests run (``tests/test_scripts.py``,
``tests/test_experiments.py``; ``bench_table`` and ``same_verdicts`` measure nothing and
``own_flight_file`` takes a minute as it is: they have none); none imports another.

They belong to the checkout, not to the installed package (the wheel holds ``aeromag_env`` and
``agents`` only): they reproduce the committed results of this source tree, some read its tests
(``experiments/fault_suite.py``) or write its documentation's data, and a top-level package
named ``experiments`` in site-packages would shadow, or be shadowed by, any other project's.
Run them from the checkout's root as modules (``python -m experiments.hidden_effects``), or from
anywhere by their path (``python ~/aeromag/experiments/hidden_effects.py``): run by its path, a
script puts its own checkout first on ``sys.path``, so it runs that checkout's packages even
where another copy is installed. Every default output is a git-ignored folder under
``results/`` (relative to the current folder); the committed data are written only when named
(``--out docs/discovery``, ``--data docs/learners``).
"""
