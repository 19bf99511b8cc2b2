"""FreqBRDF: fast, uncertainty-aware SVBRDF recovery by frequency-domain analysis.

The package holds the pure numerical functions (numpy in, numpy out) behind
the Snakemake pipeline; Mitsuba is only touched by :mod:`freqbrdf.scene.render` and
:mod:`freqbrdf.util.mitsuba_setup`, and only after an entry script has called
:func:`freqbrdf.util.mitsuba_setup.setup_mitsuba`.

The version is ``workflow/pyproject.toml``'s alone (CHANGELOG.md): this file is a code input
of every rule, so a version here would make each release rerun every job.
"""
