"""Evaluation and report: metrics, tables and claims, figures."""
