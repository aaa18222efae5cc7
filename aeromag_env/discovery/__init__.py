"""Discrepancy workflow: where a measured flight and the model disagree, and which effect is
missing."""
