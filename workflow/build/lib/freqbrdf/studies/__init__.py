"""Studies beyond the benchmark's tables: views sweep, view selection, entropy agreement, stress captures."""
