"""A downstream brake controller of train_dynamics on its typed messages (test support)."""
