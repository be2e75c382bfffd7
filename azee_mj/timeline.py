"""Scheduling blocks per articulator track, interpolation between postures, and rollout."""
