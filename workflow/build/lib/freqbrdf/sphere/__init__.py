"""Functions on the sphere: spherical harmonics, the BRDF's parameters and the model's lobes."""
