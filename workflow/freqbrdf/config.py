"""The run's configuration as the Snakefile handles it when it loads: layered on the embedded
default, checked against the schema and across keys, and recorded for a later report.

On the top floor of the package (docs/modules.md, "Floors"): it checks names against the
catalogues of several stages, and no library module imports it. What scripts and rules
need of the config lives below: `freqbrdf.util.seeds`, `freqbrdf.util.sizing`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

from freqbrdf.capture.sfm_options import CONFIG_PREFIX, SfmOptions
from freqbrdf.methods import METHODS
from freqbrdf.scene.meshes import OBJECTS
from freqbrdf.scene.scans import SCANS
from freqbrdf.util.io import atomic_path


# One procedural environment of each kind (freqbrdf.scene.envmaps) that every config may name
# without defining it under ``envs`` (`with_built_in_envs`), in config/tiny.yaml's settings.
# Named apart from the captured maps (freqbrdf.scene.hdri.MAPS has a "studio"), so that a name
# says which light it is. Here, not in envmaps, so that it is config: rules that build maps
# do not rerun when it is edited, only those whose environment's settings change.
BUILT_IN_ENVS: Mapping[str, Mapping[str, Any]] = MappingProxyType({
    "procedural_studio": MappingProxyType({"kind": "studio", "seed": 1, "lights": 3, "light_radius_deg": 22.0}),
    "procedural_museum": MappingProxyType({"kind": "museum", "seed": 2, "lamps": 9, "lamp_radius_deg": 2.5}),
    "procedural_sunny": MappingProxyType({"kind": "sunny", "sun_elevation_deg": 40.0, "sun_azimuth_deg": 60.0,
                                          "turbidity": 3.0, "ground_albedo": 0.25}),
    "procedural_overcast": MappingProxyType({"kind": "overcast", "ground_albedo": 0.25, "horizon_blur_deg": 12.0}),
})


class ConfigError(ValueError):
    """A configuration value is invalid; the message names the key."""


def merge_config(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``override`` layered on ``base``, as Snakemake layers config files: mappings are merged key
    by key, at every depth; any other value (lists included) replaces the base's. Neither
    argument is modified."""
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = merge_config(merged[key], value)
        else:
            merged[key] = value
    return merged


def with_defaults(config: dict[str, Any], default: str | Path) -> None:
    """Fill in place what ``config`` leaves out from the YAML file ``default`` (`merge_config`).

    A run from the command line already starts from the default (the Snakefile's
    ``configfile``), so this changes nothing there; a workflow that uses this one as a module
    passes its own config, which replaces the default, and may give only the keys it changes.
    """
    import yaml

    path = Path(default)
    if not path.is_file():
        raise ConfigError(f"{path}: the embedded default config is missing")
    merged = merge_config(yaml.safe_load(path.read_text()) or {}, config)
    config.clear()
    config.update(merged)


def run_config(path: str | Path, default: str | Path) -> dict[str, Any]:
    """The config a run of the YAML file ``path`` (a preset, or a run's recorded config) had:
    layered on the YAML file ``default`` (`with_defaults`), with the built-in environments
    (`with_built_in_envs`), as the Snakefile builds it; for the benches."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such config file")
    config = yaml.safe_load(path.read_text()) or {}
    with_defaults(config, default)
    with_built_in_envs(config)
    return config


def with_built_in_envs(config: dict[str, Any]) -> None:
    """Add to ``config["envs"]``, in place and after its own, each built-in procedural
    environment (`BUILT_IN_ENVS`) it does not define itself.

    A run lit by procedural light then needs no ``envs`` block; one of the config's own of the
    same name replaces the built-in.
    """
    own = dict(config.get("envs") or {})
    config["envs"] = own | {name: dict(settings) for name, settings in BUILT_IN_ENVS.items() if name not in own}


def is_captured(settings: Mapping[str, Any]) -> bool:
    """Whether an ``envs`` entry is a captured map (kind hdri, read from the asset package)."""
    return settings["kind"] == "hdri"


def relight_envs(envs: Mapping[str, Mapping[str, Any]], choice: str | Sequence[str], env: str,
                 seen: Sequence[str]) -> list[str]:
    """The environments a synthetic capture's estimate is relit under (``evaluate.relight_envs``).

    Parameters
    ----------
    envs : mapping
        The run's ``envs`` (`with_built_in_envs`), name -> settings, in config order.
    choice : str or sequence of str
        ``held_out``: every environment of ``envs`` lit the way ``env`` is (a captured map, or
        procedural light) whose light the estimate has not seen; ``all``: every one lit that
        way; else the names themselves. Keeping to the capture's kind of light means a run
        under procedural light never needs the captured maps' package, nor a run under
        captured maps the built-in procedural ones. A light defined under two names (a
        preset's ``studio`` and the built-in ``procedural_studio``) counts once, under its
        first name.
    env : str
        The environment of the capture (for a merge, one of those merged).
    seen : sequence of str
        The environments the estimate has seen: the capture's own, or those of every capture
        a merge merges.

    Returns
    -------
    list of str
        Names in ``envs`` order (a list ``choice``: its own order).

    Raises
    ------
    ConfigError
        ``env`` is not under ``envs``.
    """
    if not isinstance(choice, str):
        return list(choice)
    if env not in envs:
        raise ConfigError(f"config key envs: {env!r} is not defined (defined: {sorted(envs)})")
    lights, names = [], []
    for name, settings in envs.items():
        if is_captured(settings) == is_captured(envs[env]) and dict(settings) not in lights:
            lights.append(dict(settings))
            names.append(name)
    seen_lights = [dict(envs[name]) for name in seen if name in envs]
    return names if choice == "all" else [name for name in names if dict(envs[name]) not in seen_lights]


def reports_last_run(argv: Sequence[str], overwrite_config: Mapping[str, Any]) -> bool:
    """Whether this invocation only builds a report and brings no config of its own.

    ``snakemake --report [FILE]`` (not ``--report-after-run``, which runs the workflow
    first) with no ``--configfile`` or ``--config`` (Snakemake's
    ``workflow.config_settings.overwrite_config``, empty then; a profile's count too).
    Such a report is of the run already made in the directory, so the Snakefile then
    takes that run's config (`use_run_config`): without it, a report after a run of a
    preset (``--configfile config/tiny.yaml``) would look for the default config's
    outputs and stop at the first (``... marked for report but does not exist``).

    Parameters
    ----------
    argv : sequence of str
        The command line (``sys.argv``): Snakemake tells a Snakefile nothing else of a
        report, whose DAG is built after the Snakefile has run.
    overwrite_config : mapping
        The values given on the command line or in a profile, from files or not.
    """
    args = list(argv[1:])
    report = any(a == "--report" or a.startswith("--report=") for a in args)
    return report and "--report-after-run" not in args and not overwrite_config


def builds_report(argv: Sequence[str]) -> bool:
    """Whether this invocation builds a Snakemake report (``--report``, ``--report-after-run``)."""
    return any(a.startswith("--report") for a in argv[1:])


def record_run_config(config: Mapping[str, Any], path: str | Path) -> None:
    """Write ``config`` (the run's, complete) to the YAML file ``path``, atomically.

    The Snakefile's ``onsuccess`` writes it (:data:`freqbrdf.layout.RUN_CONFIG`) for
    `reports_last_run` to find.
    """
    import json

    import yaml

    plain = json.loads(json.dumps(config, default=str))  # OrderedDicts (JSON config files) and Paths
    with atomic_path(path) as tmp:
        tmp.write_text("# The config of the last successful run in this directory, written when it ended;\n"
                       "# `snakemake --report` without --configfile or --config reports that run under it.\n"
                       + yaml.safe_dump(plain, sort_keys=False))


def use_run_config(config: dict[str, Any], path: str | Path) -> bool:
    """Replace ``config`` in place by the recorded run config at ``path`` (`record_run_config`),
    if there is one; whether there was."""
    import yaml

    path = Path(path)
    if not path.is_file():
        return False
    recorded = yaml.safe_load(path.read_text())
    if not isinstance(recorded, dict):
        raise ConfigError(f"{path}: not a run's config (a mapping); remove it, or give --configfile")
    config.clear()
    config.update(recorded)
    return True


def _key_path(path) -> str:
    return ".".join(str(p) for p in path) or "<top level>"


def check_config(config: dict[str, Any], schema: str | Path) -> None:
    """Validate ``config`` against the JSON schema, then across keys.

    Uses :func:`snakemake.utils.validate` (which also fills schema defaults)
    and turns its multi-line report into one line naming the offending key.

    Parameters
    ----------
    config : dict
        The merged Snakemake configuration.
    schema : path-like
        JSON schema (YAML) file.

    Raises
    ------
    ConfigError
        One line: ``config key <dotted.path>: <what is wrong>``.
    """
    _check_schema(config, schema)
    _check_env_names(config)
    _check_colmap(config["poses"]["colmap"])
    _check_extra_captures(config)
    _check_framing(config["render"])


def _check_schema(config: dict[str, Any], schema: str | Path) -> None:
    """Snakemake's schema validation (fills defaults), its report cut to the best-matching error."""
    import jsonschema
    import yaml
    from snakemake.utils import validate

    try:
        validate(config, str(schema))
    except Exception:
        with open(schema) as f:
            schema_dict = yaml.safe_load(f)
        validator = jsonschema.Draft202012Validator(schema_dict)
        error = jsonschema.exceptions.best_match(validator.iter_errors(config))
        if error is None:  # snakemake failed for another reason; let it speak
            raise
        raise ConfigError(f"config key {_key_path(error.absolute_path)}: {error.message}") from None


# An environment is a name under ``envs`` with its settings (or a built-in); a newcomer often writes the kind instead.
_DEFINE_ONE = (f"; name a built-in ({', '.join(BUILT_IN_ENVS)}) or define each under envs with its kind and "
               "settings, e.g. envs: {studio: {kind: studio, seed: 1, lights: 3, light_radius_deg: 22.0}}")


def _check_env_names(config: dict[str, Any]) -> None:
    """Environments and methods named anywhere are defined (under ``envs``, in the method registry)."""
    unknown = [e for e in config["capture_envs"] if e not in config["envs"]]
    if unknown:
        raise ConfigError(f"config key capture_envs: {unknown} not defined under envs "
                          f"(defined: {sorted(config['envs'])}){_DEFINE_ONE}")
    relight_envs = config["evaluate"]["relight_envs"]
    unknown = [e for e in relight_envs if e not in config["envs"]] if isinstance(relight_envs, list) else []
    if unknown:
        raise ConfigError(f"config key evaluate.relight_envs: {unknown} not defined under envs "
                          f"(defined: {sorted(config['envs'])}){_DEFINE_ONE}")
    unknown = [m for m in config["methods"] if m not in METHODS]
    if unknown:
        raise ConfigError(f"config key methods: {unknown} are not registered methods (freqbrdf.methods: {list(METHODS)})")
    relit = config["evaluate"]["relight_methods"]
    unknown = [m for m in relit if m not in config["methods"]] if isinstance(relit, list) else []
    if unknown:
        raise ConfigError(f"config key evaluate.relight_methods: {unknown} are not among the run's methods "
                          f"({config['methods']})")


def _check_colmap(colmap: dict[str, Any]) -> None:
    """``poses.colmap`` maps onto `SfmOptions` and leaves the pipeline's own keys alone."""
    for key in ("seed", "num_threads"):  # set by the pipeline (config seed, rule threads)
        if key in colmap:
            raise ConfigError(f"config key {CONFIG_PREFIX}{key}: set by the pipeline, not in config")
    try:
        SfmOptions.from_config(colmap)
    except ValueError as error:
        raise ConfigError(f"config key {error}") from None


def _check_extra_captures(config: dict[str, Any]) -> None:
    """Real and stress captures have names of their own and consistent settings."""
    catalogue = (*OBJECTS, *SCANS)
    for name, capture in config["real_captures"].items():
        if name in catalogue:
            raise ConfigError(f"config key real_captures.{name}: the name is taken by a synthetic object")
        if capture["env"] in config["envs"]:
            raise ConfigError(f"config key real_captures.{name}.env: {capture['env']!r} is taken by a synthetic environment")
    for name, capture in config["stress_captures"].items():
        if name in catalogue or name in config["real_captures"]:
            raise ConfigError(f"config key stress_captures.{name}: the name is taken by an object or a real capture")
        if capture["env"] not in config["envs"]:
            raise ConfigError(f"config key stress_captures.{name}.env: {capture['env']!r} not defined under envs "
                              f"(defined: {sorted(config['envs'])})")
        pair = capture.get("pair")
        if pair is not None and (pair not in config["stress_captures"] or pair == name):
            raise ConfigError(f"config key stress_captures.{name}.pair: {pair!r} is not another stress capture")
        if capture.get("clearcoat", 0.0) > 0.0 and capture.get("model", "principled") != "principled":
            raise ConfigError(f"config key stress_captures.{name}.clearcoat: needs model principled, "
                              f"not {capture['model']!r}")


def _check_framing(render: dict[str, Any]) -> None:
    """The camera's field of view frames the unit-radius object from its distance."""
    half_span = math.degrees(math.asin(1.0 / render["camera_distance"]))
    if half_span >= render["fov_deg"] / 2.0:
        raise ConfigError(
            f"config key render.fov_deg: {render['fov_deg']} degrees is too narrow to frame the object "
            f"(radius 1) from camera_distance {render['camera_distance']}; it needs more than {2 * half_span:.1f}"
        )
