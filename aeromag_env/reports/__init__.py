"""Interactive HTML reports: one self-contained page per run (Bokeh, imported lazily).

Each page function takes plain data — the report dict a job writes to ``report.json`` and
numpy arrays — and returns the HTML text, which the job writes beside ``report.json`` with its
output set. Nothing here imports the compensation, environment or agents layers, so every job
can call it.

* :func:`compensate_page` (with :func:`compensate_arrays`): one compensated flight.
* :func:`calibrate_page`: a calibration, its figure of merit box by box.
* :func:`discover_page`: the discrepancy workflow's residual, gap, candidates and caveats.
* :func:`evaluate_page`: RMSE per flight per policy, normalized scores, Q/R actions.
* :func:`train_page`: the learning curve of one or more training runs.
* :func:`fleet_page`: the index of a fleet run, one sortable row per flight.
"""

from __future__ import annotations

from aeromag_env.reports.calibrate import calibrate_page
from aeromag_env.reports.compensate import compensate_arrays, compensate_page
from aeromag_env.reports.discover import discover_page
from aeromag_env.reports.evaluate import evaluate_page
from aeromag_env.reports.fleet import fleet_page
from aeromag_env.reports.train import train_page

#: The file name of a run's page, beside its ``report.json``.
PAGE = "report.html"
#: The file name of a fleet's index page, beside ``fleet.csv``.
FLEET_PAGE = "index.html"

__all__ = [
    "FLEET_PAGE",
    "PAGE",
    "calibrate_page",
    "compensate_arrays",
    "compensate_page",
    "discover_page",
    "evaluate_page",
    "fleet_page",
    "train_page",
]
