"""FreqBRDF: fast, uncertainty-aware SVBRDF recovery by frequency-domain analysis.

The package holds the pure numerical functions (numpy in, numpy out) behind
the Snakemake pipeline; Mitsuba is only touched by :mod:`freqbrdf.scene.render` and
:mod:`freqbrdf.util.mitsuba_setup`, and only after an entry script has called
:func:`freqbrdf.util.mitsuba_setup.setup_mitsuba`.
"""

__version__ = "0.1.0"
