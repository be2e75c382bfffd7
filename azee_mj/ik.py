"""Posture solving: AZee constraints as MuJoCo equality constraints and extra rows, solved with joint limits and self-collision."""
