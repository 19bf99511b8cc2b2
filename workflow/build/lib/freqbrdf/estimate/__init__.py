"""Estimators: SH fits, the spectrum search, the light model, the gradient-descent estimator, Mitsuba's baseline, merges."""
