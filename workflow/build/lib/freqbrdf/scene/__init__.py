"""Synthetic scenes: procedural objects and textures, environment maps, cameras, rendering, ray casting."""
