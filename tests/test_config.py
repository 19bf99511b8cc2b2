"""Configuration: the shipped presets validate; every mistake is one line naming the key."""

import copy
import re
import subprocess
import sys

import pytest
import yaml
from snakemake.utils import update_config
from workflow_runs import planned_jobs

from freqbrdf.config import (BUILT_IN_ENVS, ConfigError, builds_report, check_config, relight_envs, run_config,
                             with_built_in_envs)
from freqbrdf.scene.envmaps import ENV_KINDS
from freqbrdf.scene.hdri import MAPS
from freqbrdf.util.seeds import derived_seed
from freqbrdf.util.sizing import SIZE_KINDS, size_factor


@pytest.fixture(scope="module")
def schema(repo):
    return repo / "workflow" / "schemas" / "config.schema.yaml"


@pytest.fixture()
def default(repo):
    return yaml.safe_load((repo / "config" / "config.yaml").read_text())


@pytest.mark.parametrize("preset", ["paper.yaml", "tiny.yaml", "tuning.yaml", "stress.yaml", "benchmark.yaml"])
def test_shipped_configs_validate(repo, schema, default, preset):
    check_config(copy.deepcopy(default), schema)
    merged = copy.deepcopy(default)
    update_config(merged, yaml.safe_load((repo / "config" / preset).read_text()))
    check_config(merged, schema)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda c: c["render"].update(sppp=3), r"config key render: .*'sppp' was unexpected"),
        (lambda c: c["render"].update(spp=0), r"config key render\.spp: 0 is less than the minimum of 1"),
        (lambda c: c["envs"]["studio"].update(lamps=3), r"config key envs\.studio: .*'lamps' was unexpected"),
        (lambda c: c["envs"]["sunny"].update(kind="sunset"), r"config key envs\.sunny\.kind: 'sunset' is not one of"),
        (lambda c: c.update(objects=["teapot"]), r"config key objects\.0: 'teapot' is not one of"),
        (lambda c: c.update(methods=["freq", "nerf"]), r"config key methods: \[.nerf.\] are not registered methods"),
        (lambda c: c.update(capture_envs=["beach"]), r"config key capture_envs: \['beach'\] not defined under envs"),
        (lambda c: c["evaluate"].update(relight_envs=["beach"]), r"config key evaluate\.relight_envs: \['beach'\] not defined"),
        (lambda c: c["evaluate"].update(relight_envs="others"), r"config key evaluate\.relight_envs: 'others' is not valid"),
        (lambda c: c["evaluate"].update(relight_methods=["freq", "nerf"]),
         r"config key evaluate\.relight_methods: \['nerf'\] are not among the run's methods"),
        (lambda c: c["render"].update(fov_deg=10.0), r"config key render\.fov_deg: 10.0 degrees is too narrow"),
        (lambda c: c.pop("seed"), r"'seed' is a required property"),
        (lambda c: c["poses"]["colmap"].update(peak_treshold=0.01), r"config key poses\.colmap\.peak_treshold: unknown option"),
        (lambda c: c["poses"]["colmap"].update(max_ratio=1.5), r"config key poses\.colmap\.max_ratio: 1\.5 must be in \[0, 1\]"),
        (lambda c: c["poses"]["colmap"].update(seed=3), r"config key poses\.colmap\.seed: set by the pipeline"),
        (lambda c: c.update(real_captures={"torus": {"dir": "x", "env": "e"}}), r"real_captures\.torus: the name is taken"),
        (lambda c: c.update(real_captures={"pot": {"dir": "x", "env": "sunny"}}), r"real_captures\.pot\.env: 'sunny' is taken"),
        (lambda c: c.update(real_captures={"pot": {"dir": "x"}}), r"config key real_captures\.pot: 'env' is a required property"),
        (lambda c: c.update(real_captures={"pot": {"dir": "x", "env": "e", "up_axis": "x"}}),
         r"config key real_captures\.pot\.up_axis: 'x' is not one of \['y', 'z'\]"),
        (lambda c: c.update(real_captures={"pot": {"dir": "x", "env": "e", "camera": "vulkan"}}),
         r"config key real_captures\.pot\.camera: 'vulkan' is not one of"),
        (lambda c: c.update(stress_captures={"odd": {"object": "sphere", "env": "beach"}}),
         r"config key stress_captures\.odd\.env: 'beach' not defined under envs"),
        (lambda c: c.update(stress_captures={"torus": {"object": "sphere", "env": "studio"}}),
         r"config key stress_captures\.torus: the name is taken"),
        (lambda c: c.update(stress_captures={"odd": {"object": "sphere", "env": "studio", "pair": "odd"}}),
         r"config key stress_captures\.odd\.pair: 'odd' is not another stress capture"),
        (lambda c: c.update(stress_captures={"odd": {"object": "sphere", "env": "studio", "model": "beckmann_blend",
                                                     "clearcoat": 0.5}}),
         r"config key stress_captures\.odd\.clearcoat: needs model principled"),
        (lambda c: c.update(stress_captures={"odd": {"object": "sphere", "env": "studio",
                                                     "occluder": {"height": -0.5, "radius": 2}}}),
         r"config key stress_captures\.odd\.occluder\.height: -0\.5 is greater than the maximum of -1"),
        (lambda c: c["envs"]["studio"].update(blur=-1), r"config key envs\.studio\.blur: -1 is less than the minimum"),
        (lambda c: c["poses"].update(compare=["sfm"]), r"config key poses\.compare\.0: 'sfm' is not one of"),
        (lambda c: c["optimise"].update(solver="newton"), r"config key optimise\.solver: 'newton' is not one of \['adam', 'lm'\]"),
        (lambda c: c["optimise"].update(sweeps=0), r"config key optimise\.sweeps: 0 is less than the minimum of 1"),
    ],
)
def test_mistakes_give_one_line_naming_the_key(repo, schema, default, edit, message):
    # the tiny preset's procedural environments (studio, sunny, ...), which the edits name
    update_config(default, {"envs": yaml.safe_load((repo / "config" / "tiny.yaml").read_text())["envs"]})
    edit(default)
    with pytest.raises(ConfigError, match=message) as info:
        check_config(default, schema)
    assert "\n" not in str(info.value)


def test_an_undefined_environment_says_how_to_define_one_and_the_example_works(schema, default):
    """A newcomer writes capture_envs: [studio], the kind, not a name under envs: the message names
    the built-ins and shows a definition, and either, named or pasted in, passes."""
    default["capture_envs"] = ["studio"]
    with pytest.raises(ConfigError, match=r"capture_envs: \['studio'\] not defined under envs") as info:
        check_config(copy.deepcopy(default), schema)
    assert all(name in str(info.value) for name in BUILT_IN_ENVS)
    named = copy.deepcopy(default) | {"capture_envs": ["procedural_studio"]}
    with_built_in_envs(named)
    check_config(named, schema)
    update_config(default, yaml.safe_load(str(info.value).split("e.g. ", 1)[1]))
    check_config(default, schema)


def test_built_in_environments_are_one_of_each_procedural_kind_named_apart_from_the_maps():
    assert sorted(settings["kind"] for settings in BUILT_IN_ENVS.values()) == sorted(ENV_KINDS)
    assert not set(BUILT_IN_ENVS) & set(MAPS)


def test_a_config_names_a_built_in_environment_and_its_own_definition_replaces_it(schema, default):
    default["capture_envs"] = ["procedural_museum"]
    default["envs"]["procedural_studio"] = {"kind": "studio", "seed": 7}
    with_built_in_envs(default)
    check_config(default, schema)
    assert list(default["envs"]) == ["sky", "lobby", "city", "procedural_studio", "procedural_museum",
                                      "procedural_sunny", "procedural_overcast"]
    assert default["envs"]["procedural_studio"] == {"kind": "studio", "seed": 7}
    assert default["envs"]["procedural_museum"] == dict(BUILT_IN_ENVS["procedural_museum"])


def test_relighting_keeps_to_the_capture_s_kind_of_light():
    envs = {"sky": {"kind": "hdri", "map": "sky"}, "lobby": {"kind": "hdri", "map": "lobby"}, "studio": {"kind": "studio"},
            "rain": {"kind": "overcast"}}
    assert relight_envs(envs, "held_out", "sky", ["sky"]) == ["lobby"]
    assert relight_envs(envs, "held_out", "studio", ["studio"]) == ["rain"]
    assert relight_envs(envs, "held_out", "sky", ["sky", "lobby"]) == []  # a merge of both captures
    assert relight_envs(envs, "all", "rain", ["rain"]) == ["studio", "rain"]
    assert relight_envs(envs, ["studio", "sky"], "sky", ["sky"]) == ["studio", "sky"]  # a list is taken as given
    # one light under two names (a preset's studio and the built-in) is one light: held out
    # from a studio capture, and relit under once
    twice = envs | {"procedural_studio": {"kind": "studio"}, "procedural_rain": {"kind": "overcast"}}
    assert relight_envs(twice, "held_out", "studio", ["studio"]) == ["rain"]
    assert relight_envs(twice, "held_out", "procedural_studio", ["procedural_studio"]) == ["rain"]
    assert relight_envs(twice, "all", "procedural_studio", ["procedural_studio"]) == ["studio", "rain"]
    with pytest.raises(ConfigError, match=r"config key envs: 'beach' is not defined"):
        relight_envs(envs, "held_out", "beach", ["beach"])


def test_only_the_methods_relight_methods_names_are_relit(repo, tmp_path):
    """The tiny preset relights each method's estimate in one job; a list leaves the others out."""
    command = [sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d", str(tmp_path), "-n",
               "--configfile", str(repo / "config" / "tiny.yaml")]
    every = subprocess.run(command, capture_output=True, text=True, timeout=120)
    some = subprocess.run([*command, "--config", "evaluate={'relight_methods': ['freq', 'mitsuba']}"],
                          capture_output=True, text=True, timeout=120)
    assert every.returncode == 0 and some.returncode == 0, some.stderr[-2000:]
    assert planned_jobs(every.stdout)["relight"] > 2 and planned_jobs(some.stdout)["relight"] == 2
    assert set(re.findall(r"output: results/relight/sphere/studio/gt/([\w+]+)$", some.stdout, re.M)) == {"freq", "mitsuba"}


def test_a_run_under_built_in_light_plans_neither_the_asset_package_nor_an_envs_block(repo, tmp_path):
    """objects, capture_envs and methods alone: procedural light needs no envs block, and relit under
    the other built-ins it never fetches the captured maps' package; the default run does."""
    config = tmp_path / "procedural.yaml"
    config.write_text("objects: [sphere]\ncapture_envs: [procedural_studio]\nmethods: [spectrum, freq]\n")
    plans = {}
    for name, extra in (("procedural", ["--configfile", str(config)]), ("default", [])):
        done = subprocess.run([sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"),
                               "-d", str(tmp_path), "-n", *extra], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr[-2000:]
        plans[name] = done.stdout
    assert "fetch_asset_package" in planned_jobs(plans["default"])
    jobs = planned_jobs(plans["procedural"])
    assert "fetch_asset_package" not in jobs and jobs["build_env"] == 4 and jobs["relight"] == 2
    built = set(re.findall(r"results/envs/(\w+)\.exr", plans["procedural"]))
    assert built == set(BUILT_IN_ENVS)


def test_snakemake_stops_at_once_on_a_bad_key(repo, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("render:\n  spp: -4\n")
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d", str(tmp_path), "-n", "--configfile", str(bad)],
        capture_output=True, text=True, timeout=120,
    )
    assert run.returncode != 0
    lines = [line for line in (run.stdout + run.stderr).splitlines() if "config key" in line]
    assert lines == ["config key render.spp: -4 is less than the minimum of 1"]


def test_derived_seeds_are_stable_and_distinct():
    assert derived_seed(0, "object", "torus") == derived_seed(0, "object", "torus")
    seeds = {derived_seed(s, "object", name) for s in (0, 1) for name in ("sphere", "torus", "die")}
    assert len(seeds) == 6
    assert all(0 <= s < 2**31 for s in seeds)


def test_a_real_capture_gets_the_documented_defaults(schema, default):
    default["real_captures"] = {"pot": {"dir": "x", "env": "e"}}
    check_config(default, schema)
    assert default["real_captures"]["pot"] == {"dir": "x", "env": "e", "up_axis": "y", "camera": "opengl",
                                               "align_env": False}


def schema_leaves(node: dict, prefix: str = "") -> list[str]:
    """Dotted names of the schema's leaf keys (keys whose value is not an object with properties);
    ``additionalProperties`` schemas (named entries such as ``envs.{env}``) count as one leaf."""
    leaves = []
    for key, sub in node.get("properties", {}).items():
        name = f"{prefix}.{key}" if prefix else key
        leaves += schema_leaves(sub, name) if sub.get("properties") else [name]
    return leaves


def test_every_schema_key_is_documented_in_config_readme(repo, schema):
    text = (repo / "config" / "README.md").read_text()
    leaves = schema_leaves(yaml.safe_load(schema.read_text()))
    assert len(leaves) > 40  # the walk reached the nested sections
    missing = [name for name in leaves if f"`{name}`" not in text]
    assert not missing, f"config/README.md does not document {missing}"


def test_size_factor_is_one_on_the_default_and_grows_with_the_work(repo, default):
    for kind in SIZE_KINDS:
        assert size_factor(default, kind) == 1.0
    paper = copy.deepcopy(default)
    update_config(paper, yaml.safe_load((repo / "config" / "paper.yaml").read_text()))
    pixels = (512 / 256) ** 2 * 100 / 24
    assert size_factor(paper, "pixels") == pytest.approx(pixels)
    assert size_factor(paper, "samples") == pytest.approx(pixels * 256 / 64)
    assert size_factor(paper, "texels") == pytest.approx((512 / 256) ** 2 * 100 / 24)
    assert size_factor(paper, "inverse") == pytest.approx(pixels * 32 / 8 * 10 / 48)
    assert size_factor(paper, "agreement") == pytest.approx(100 / 24 * 1024 / 256 * 16 / 8)
    with pytest.raises(ValueError, match="size kind"):
        size_factor(default, "voxels")


def test_optimise_settings_follow_the_config(default):
    from freqbrdf.estimate.optimise.settings import OptimiseSettings, identifiable_roughness

    opt = default["optimise"] | {"solver": "lm", "sweeps": 7, "sweep_refit_every": 3, "min_roughness": "auto",
                                 "lobe": "gaussian"}
    settings = OptimiseSettings.from_config(opt, workers=2)
    assert (settings.solver, settings.sweeps, settings.sweep_refit_every, settings.workers) == ("lm", 7, 3, 2)
    assert settings.lobe == "gaussian" and OptimiseSettings.from_config(default["optimise"]).lobe == "ggx"
    assert settings.min_roughness == identifiable_roughness(opt["lmax"], lobe="gaussian")
    ggx = OptimiseSettings.from_config(opt | {"lobe": "ggx"})
    assert ggx.min_roughness == identifiable_roughness(opt["lmax"], lobe="ggx") > settings.min_roughness
    assert (settings.iterations, settings.lr, settings.tv_weight) == (opt["iterations"], opt["lr"], opt["tv_weight"])
    assert OptimiseSettings.from_config(default["optimise"]).solver == "adam"


def test_the_paper_preset_is_paper_yaml_over_the_default(repo, schema, default):
    """One place for the estimator's defaults: the config's; ``OptimiseSettings`` has none for the
    fields it sets, and its preset ``paper()`` is what ``config/paper.yaml`` over the default builds."""
    import dataclasses

    from freqbrdf.estimate.optimise.settings import OptimiseSettings

    config_set = set(yaml.safe_load(schema.read_text())["properties"]["optimise"]["properties"])
    held = config_set - {"init", "lmax", "point_sources"} | {"grid_start"}  # init: grid -> grid_start
    assert {f.name for f in dataclasses.fields(OptimiseSettings)
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING} == held
    with pytest.raises(TypeError):
        OptimiseSettings()
    merged = copy.deepcopy(default)
    update_config(merged, yaml.safe_load((repo / "config" / "paper.yaml").read_text()))
    paper, preset = OptimiseSettings.from_config(merged["optimise"]), OptimiseSettings.paper()
    assert {name: getattr(paper, name) for name in held} == {name: getattr(preset, name) for name in held}
    assert paper == preset  # the implementation's own fields keep their code defaults in both
    assert merged["optimise"]["point_sources"]["max_radius_deg"] == 0  # the paper's light: all through the SH
    assert OptimiseSettings.from_config(default["optimise"]) != preset  # the default is tuned away from it
    assert OptimiseSettings.paper(iterations=300, lr=0.01) == dataclasses.replace(preset, iterations=300, lr=0.01)
    with pytest.raises(ValueError, match="lr must be a finite number > 0"):
        OptimiseSettings.paper(lr=0)


def test_merge_config_layers_mappings_at_every_depth_and_replaces_the_rest() -> None:
    from freqbrdf.config import merge_config

    base = {"a": {"b": 1, "c": [1, 2], "d": {"e": 1}}, "f": 2}
    override = {"a": {"c": [3], "d": {"g": 4}}, "h": 5}
    assert merge_config(base, override) == {"a": {"b": 1, "c": [3], "d": {"e": 1, "g": 4}}, "f": 2, "h": 5}
    assert base == {"a": {"b": 1, "c": [1, 2], "d": {"e": 1}}, "f": 2}  # not modified


def test_with_defaults_fills_a_partial_config_in_place(tmp_path) -> None:
    import yaml

    from freqbrdf.config import ConfigError, with_defaults

    default = tmp_path / "default.yaml"
    default.write_text(yaml.safe_dump({"seed": 1, "render": {"spp": 64, "resolution": 256}}))
    config = {"render": {"spp": 4}}
    with_defaults(config, default)
    assert config == {"seed": 1, "render": {"spp": 4, "resolution": 256}}
    with pytest.raises(ConfigError, match="missing.yaml: the embedded default config is missing"):
        with_defaults({}, tmp_path / "missing.yaml")


def test_a_report_with_no_config_of_its_own_takes_the_last_runs():
    from freqbrdf.config import reports_last_run

    for argv in (["--report"], ["--report", "results/report.html"], ["--report=r.html", "-d", "w"]):
        assert reports_last_run(["snakemake", *argv], {})
    assert not reports_last_run(["snakemake", "--report", "r.html"], {"render": {"spp": 4}})  # --configfile/--config
    assert not reports_last_run(["snakemake", "--cores", "2", "--report", "r.html", "--report-after-run"], {})
    for argv in (["--cores", "2"], ["-n"], ["--reporter", "html"], ["--report-stylesheet", "s.css"], ["--unlock"]):
        assert not reports_last_run(["snakemake", *argv], {})


def test_a_report_is_built_by_report_and_report_after_run_only():
    assert builds_report(["snakemake", "--report", "r.html"]) and builds_report(["snakemake", "--report-after-run"])
    assert not builds_report(["snakemake", "--cores", "2", "results/report.html"])


def test_a_bench_reads_a_preset_as_the_snakefile_does(repo, tmp_path):
    config = run_config(repo / "config" / "tiny.yaml", repo / "config" / "config.yaml")
    assert config["objects"] == ["sphere"] and config["render"]["resolution"] == 32  # the preset's
    assert config["optimise"]["lmax"] == 20 and "procedural_sunny" in config["envs"]  # the default's, the built-ins
    with pytest.raises(ConfigError, match="nope.yaml: no such config file"):
        run_config(tmp_path / "nope.yaml", repo / "config" / "config.yaml")


def test_the_recorded_run_config_replaces_the_config_whole(tmp_path):
    from collections import OrderedDict

    from freqbrdf.config import record_run_config, use_run_config

    path = tmp_path / "results" / "run_config.yaml"
    config = {"objects": ["sphere"], "render": {"spp": 4}}
    assert not use_run_config(config, path) and config == {"objects": ["sphere"], "render": {"spp": 4}}
    record_run_config({"objects": ["torus"], "render": OrderedDict(spp=8), "dir": tmp_path}, path)  # a JSON file's, a Path
    assert use_run_config(config, path)
    assert config == {"objects": ["torus"], "render": {"spp": 8}, "dir": str(tmp_path)}
    assert [p.name for p in path.parent.iterdir()] == ["run_config.yaml"]  # written in place, nothing left beside
    path.write_text("- not a mapping\n")
    with pytest.raises(ConfigError, match="run_config.yaml: not a run's config"):
        use_run_config(config, path)


def test_snakemake_report_follows_the_recorded_config_unless_given_one(repo, tmp_path):
    """A recorded run config with a wrong value shows which config the report's DAG is built
    from: the recorded one for the plain command, the command line's when it brings one."""
    from freqbrdf import layout
    from freqbrdf.config import record_run_config

    record_run_config({"render": {"spp": -4}}, tmp_path / layout.RUN_CONFIG)
    command = [sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d", str(tmp_path),
               "--report", str(tmp_path / "report.html")]
    plain = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert plain.returncode != 0
    assert f"Report of the last run here, under its config ({layout.RUN_CONFIG}" in plain.stdout + plain.stderr
    assert "config key render.spp: -4 is less than the minimum of 1" in plain.stdout + plain.stderr
    given = subprocess.run([*command, "--configfile", str(repo / "config" / "tiny.yaml")],
                           capture_output=True, text=True, timeout=120)
    assert "config key" not in given.stdout + given.stderr and "last run" not in given.stdout + given.stderr


def test_a_report_of_targets_short_of_the_tables_builds_and_says_it_has_no_summary(repo, tmp_path):
    """`snakemake --report r.html TARGET` after a targeted run failed on the landing page's include of
    the run summary, which rule tables writes: the page now includes it only where the tables are
    in the report, and says otherwise."""
    report = tmp_path / "r.html"
    done = subprocess.run([sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"), "-d",
                           str(tmp_path), "--configfile", str(repo / "config" / "tiny.yaml"), "--report", str(report),
                           "results/objects/sphere/base_color.exr"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    page = report.read_text()
    assert "has no summary here" in page and "Headline numbers" not in page  # the summary's second table


def test_a_missing_preset_stops_in_one_line_naming_it(repo, tmp_path):
    """Snakemake 9.27.1 answers a --configfile that does not exist with a traceback (its loader
    opens the file outside the try that would say "Config file ... not found.") before the
    Snakefile runs; its last line names the file. `make run CONFIG=...` checks first: one line."""
    import shutil

    missing = tmp_path / "nope.yaml"
    direct = subprocess.run([sys.executable, "-m", "snakemake", "-s", str(repo / "workflow" / "Snakefile"),
                             "-d", str(tmp_path), "-n", "--configfile", str(missing)],
                            capture_output=True, text=True, timeout=120)
    assert direct.returncode != 0 and str(missing) in (direct.stdout + direct.stderr).strip().splitlines()[-1]
    if shutil.which("make") is None:
        pytest.skip("no make")
    made = subprocess.run(["make", "-n", "-C", str(repo), "run", f"CONFIG={missing}"], capture_output=True, text=True,
                          timeout=60)
    assert made.returncode != 0 and "snakemake" not in made.stdout
    lines = made.stderr.strip().splitlines()
    assert len(lines) == 1 and f"CONFIG={missing}: no such file" in lines[0] and "config/tiny.yaml" in lines[0]
    planned = subprocess.run(["make", "-n", "-C", str(repo), "run", "CONFIG=config/tiny.yaml"], capture_output=True,
                             text=True, timeout=60)
    assert planned.returncode == 0 and "snakemake --cores 2 --configfile config/tiny.yaml" in planned.stdout
