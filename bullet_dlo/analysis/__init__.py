"""Closed forms, the study's table and the automatic choice of resolution (above the core, below PyBullet)."""
