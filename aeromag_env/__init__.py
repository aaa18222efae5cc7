"""Aircraft aeromagnetic compensation: simulator, compensators, tuning environment."""
