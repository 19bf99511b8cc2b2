"""What the Snakemake workflow catalog reads of this repository: its settings file, the config
schema where the template puts it, and a release version (CHANGELOG.md). The catalog's
``report: true`` is checked by building the report zip (tests/test_pipeline.py)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
DEPLOYMENTS = {"conda", "apptainer", "apptainer+conda"}
"""The catalog's software-stack-deployment keys (``--sdm conda``, ``apptainer``, both)."""


def test_the_catalog_settings_use_the_current_keys() -> None:
    usage = yaml.safe_load((REPO / ".snakemake-workflow-catalog.yml").read_text())["usage"]
    assert set(usage) == {"mandatory-flags", "software-stack-deployment", "report"}
    assert set(usage["mandatory-flags"]) == {"desc", "flags"}
    deployment = usage["software-stack-deployment"]
    assert set(deployment) == DEPLOYMENTS and all(isinstance(v, bool) for v in deployment.values())
    assert usage["report"] is True


def test_the_config_schema_is_where_the_template_puts_it() -> None:
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())
    assert schema["type"] == "object" and "properties" in schema
    assert not (REPO / "config" / "schemas").exists()


def test_the_changelog_heads_with_the_package_version() -> None:
    version = tomllib.loads((REPO / "workflow" / "pyproject.toml").read_text())["project"]["version"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", version)
    headings = re.findall(r"^## (\S+) \(\d{4}-\d{2}-\d{2}\)$", (REPO / "CHANGELOG.md").read_text(), re.M)
    assert headings and headings[0] == version
