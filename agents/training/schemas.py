"""The JSON Schema files of the hyperparameter files, made from their models.

``agents/training/hyperparams/ppo.schema.json`` (:func:`agents.training.hyperparameters.ppo_schema`)
and ``learners.schema.json``
(:func:`agents.training.learner_hyperparameters.learners_schema`) are for editors and readers:
the models check the files themselves. ``python -m agents.training.schemas`` rewrites them; a
test checks that the committed files are the ones made now.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from agents.training.hyperparameters import ppo_schema
from agents.training.learner_hyperparameters import learners_schema

HYPERPARAMS = Path(__file__).with_name("hyperparams")
#: The JSON Schemas made from the models.
PPO_SCHEMA = HYPERPARAMS / "ppo.schema.json"
LEARNERS_SCHEMA = HYPERPARAMS / "learners.schema.json"


def schemas() -> dict[Path, dict[str, Any]]:
    """Each JSON Schema file and its schema, made from the models."""
    return {PPO_SCHEMA: ppo_schema(), LEARNERS_SCHEMA: learners_schema()}


def schema_text(schema: dict[str, Any]) -> str:
    """``schema`` as the text of its file."""
    return json.dumps(schema, indent=2, ensure_ascii=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Rewrite the JSON Schema files from the models, into the folder ``argv[0]`` if given."""
    folder = Path(argv[0]) if argv else HYPERPARAMS
    for path, schema in schemas().items():
        target = folder / path.name
        target.write_text(schema_text(schema), encoding="utf-8")
        print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
