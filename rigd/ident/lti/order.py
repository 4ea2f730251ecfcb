"""Delay first, then order: the generic base model chosen from the data (to come)."""
