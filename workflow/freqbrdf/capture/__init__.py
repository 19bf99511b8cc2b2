"""Captures: their exchange layouts and meshes, camera poses by SfM, per-texel observations."""
