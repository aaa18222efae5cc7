"""Reproduce Zhang, Zhao & Chang (2014) §4 and compare with its claims.

Thin wrapper over ``aeromag reproduce-paper``: ``python experiments/reproduce_paper.py [--quick]``
writes ``results/paper/`` (report.json, fig3_field.png, fig4_states.png, fig5_compensation.png);
``--sweep 10`` repeats the setting on seeds 1–10 and prints the spread.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from aeromag_env.cli.main import main as aeromag
from aeromag_env.compensation.paper import seed_sweep


def main(argv: Sequence[str] | None = None) -> int:
    """Run the reproduction; arguments are those of ``aeromag reproduce-paper``.

    ``--sweep N`` instead runs seeds 1…N of the same setting and prints min/median/max of each
    figure (the README's robustness line).
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if "--sweep" in args:
        i = args.index("--sweep")
        n = int(args[i + 1])
        summary = seed_sweep(list(range(1, n + 1)), quick="--quick" in args)
        for key, v in summary.items():
            print(
                f"{key:34s} min {v['min']:10.4g}  median {v['median']:10.4g}  max {v['max']:10.4g}"
            )
        return 0
    if "--out" not in args:
        args += ["--out", "results/paper"]
    return aeromag(["reproduce-paper", *args])


if __name__ == "__main__":
    sys.exit(main())
