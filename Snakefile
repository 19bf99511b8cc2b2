"""FreqBRDF: fast, uncertainty-aware SVBRDF recovery from multi-view HDR captures.

snakemake --cores 2                                   # embedded default config
snakemake --cores 2 --configfile config/paper.yaml    # paper-scale preset
snakemake --report results/report.html
"""

import sys
from pathlib import Path

from snakemake.utils import min_version

min_version("9.0")


# This repository: the directory of this file, also when the workflow is used as a
# module from another (workflow.basedir is then the consumer's) or with --directory.
REPO = Path(workflow.current_basedir)
# The freqbrdf library is imported from this checkout, installed or not: Snakemake
# appends its own module path to every script's, so the jobs find the same source
# under --sdm conda, whose environment (envs/freqbrdf.yaml) cannot install it.
sys.path.insert(0, str(REPO / "workflow"))

from freqbrdf.config import check_config


# The embedded default, found next to this file; --configfile and --config values
# are layered on top of it.
configfile: REPO / "config" / "config.yaml"


check_config(config, REPO / "config" / "schemas" / "config.schema.yaml")


report: "report/workflow.rst"


include: "rules/common.smk"
include: "rules/objects.smk"
include: "rules/envs.smk"
include: "rules/captures.smk"
include: "rules/exchange.smk"
include: "rules/poses.smk"
include: "rules/observations.smk"
include: "rules/frequency.smk"
include: "rules/estimate.smk"
include: "rules/mitsuba.smk"
include: "rules/merge.smk"
include: "rules/views.smk"
include: "rules/entropy_agreement.smk"
include: "rules/view_selection.smk"
include: "rules/stress.smk"
include: "rules/relight.smk"
include: "rules/evaluate.smk"
include: "rules/report.smk"
include: "rules/export.smk"
include: "rules/targets.smk"


rule all:
    default_target: True
    input:
        ALL_TARGETS,
