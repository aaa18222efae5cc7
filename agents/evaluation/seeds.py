"""The seed ranges of the tuners, disjoint by construction: training ``[0, 50 000)``, validation
``[50 000, 100 000)``, test ``[100 000, ∞)``. A flight is drawn from its seed alone, so a policy
chosen on the training or validation seeds has never flown a test flight."""

from __future__ import annotations

TRAIN_SEEDS = range(0, 50_000)
VALIDATION_SEEDS = range(50_000, 100_000)
TEST_SEED_START = 100_000
