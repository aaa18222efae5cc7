"""The seed ranges of the tuners, disjoint by construction: training ``[0, 50 000)``, validation
``[50 000, 100 000)``, test ``[100 000, ∞)``. A flight is drawn from its seed alone, so a policy
chosen on the training or validation seeds has never flown a test flight.

Test flights are flown once per benchmark, each benchmark from its own first seed, so that no
table reports flights another table's choices saw: ``aeromag evaluate`` and the README's tables
from :data:`TEST_SEED_START` on, the learners' benchmark from 200 000
(``agents.comparison.pipeline.FIRST_SEED``), the adaptive filters' benchmark from
:data:`ADAPTIVE_BENCHMARK_FIRST_SEED`.
"""

from __future__ import annotations

TRAIN_SEEDS = range(0, 50_000)
VALIDATION_SEEDS = range(50_000, 100_000)
TEST_SEED_START = 100_000
#: The first test flight of the adaptive filters' benchmark (``experiments/adaptive_benchmark.py``):
#: fresh, above every range flown before it (100 000 on, 200 000 on).
ADAPTIVE_BENCHMARK_FIRST_SEED = 400_000
