"""MuJoCo viewer preview and offscreen rendering of rollouts."""
