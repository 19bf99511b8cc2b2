"""Exports: glTF materials, RGBE environments, the offline viewer."""
