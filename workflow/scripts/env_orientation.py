"""Rule env_orientation: the imported environment map scored over azimuth rotations, turned if asked."""

import functools

import numpy as np

from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.util.colour import LUMINANCE
from freqbrdf.scene.envmaps import turn_envmap
from freqbrdf.util.io import atomic_path, read_exr, read_json, read_views, write_exr, write_json
from freqbrdf.util.logs import run_script
from freqbrdf.scene.ply import read_ply
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.capture.observations import band_limit_parameter, edge_free_distances, observe, rasterise_uv
from freqbrdf.capture.orientation import best_azimuth, patch_index, summary
from freqbrdf.scene.raycast import distance_maps, mesh_scene, occlusion_test
from freqbrdf.sphere.sh import project_equirect

# The check needs a few hundred texels per chart, not the full atlas, and a
# bounded number of pairs: the SH basis is (pairs x (lmax + 1)^2) floats.
CHECK_RESOLUTION = 64
MAX_PAIRS = 200_000


def mirror_pairs(mi, smk, settings):
    """Luminance, world normal, mirror direction and texel patch of every observed (texel, view) pair."""
    cameras = cameras_from_json(read_json(f"{smk.input.capture}/cameras.json"), f"{smk.input.capture}/cameras.json")
    images, coverage, _ = read_views(smk.input.capture, cameras.names, cameras.width, cameras.height)
    texels = rasterise_uv(read_ply(smk.input.mesh), min(CHECK_RESOLUTION, smk.params.resolution), settings["dilate_texels"])
    scene = mesh_scene(mi, smk.input.mesh)
    distances = edge_free_distances(distance_maps(mi, scene, cameras.K, cameras.world_to_camera, cameras.width,
                                                  cameras.height), jump=settings["edge_jump"])
    placeholder = np.zeros((2, 4, 3), np.float32)  # incoming light is not used here
    obs = observe(texels, cameras, images, coverage, placeholder, functools.partial(occlusion_test, mi, scene),
                  distances=distances, min_coverage=settings["min_coverage"], ray_offset=settings["ray_offset"],
                  footprint_slack=settings["footprint_slack"])
    ti, ki = np.nonzero(obs["weight"] > 0)
    wo = obs["wo_local"][ti, ki].astype(np.float64)
    # Mirror of wo about the normal, (-x, -y, z) locally, back to world axes.
    frame = np.stack([texels.tangent[ti], texels.bitangent[ti], texels.normal[ti]], axis=1)
    mirror = np.einsum("pij,pi->pj", frame, wo * np.array([-1.0, -1.0, 1.0]))
    patch = patch_index(texels.texel[ti], texels.resolution)  # each patch has its own fit
    return obs["radiance"][ti, ki] @ LUMINANCE, texels.normal[ti], mirror, patch, len(cameras)


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    settings = smk.params.settings
    given = read_exr(smk.input.envmap)
    radiance, normal, mirror, group, n_views = mirror_pairs(mi, smk, settings)
    if not len(radiance):  # extract_observations stops on this capture, naming the unusable views
        log.warning("%s: no (texel, view) pair is observed: orientation not checked", smk.params.source)
        write_exr(smk.output.envmap, given)
        write_json(smk.output.rotation, {"degrees": 0.0})
        with atomic_path(smk.output.scores) as tmp:
            tmp.write_text("shift_columns\tdegrees\texplained\n")
        return
    if len(radiance) > MAX_PAIRS:
        keep = np.sort(np.random.default_rng(smk.params.seed).choice(len(radiance), MAX_PAIRS, replace=False))
        radiance, normal, mirror, group = radiance[keep], normal[keep], mirror[keep], group[keep]
    a_prime = band_limit_parameter(n_views, settings["band_limit"])
    coeffs = project_equirect(given @ LUMINANCE, max(smk.params.lmax, 2))
    result = best_azimuth(radiance, normal, mirror, np.unique(group, return_inverse=True)[1], coeffs, a_prime,
                          given.shape[1])
    with atomic_path(smk.output.scores) as tmp:
        tmp.write_text("shift_columns\tdegrees\texplained\n" + "".join(
            f"{s}\t{360.0 * s / given.shape[1]:.3f}\t{e:.6f}\n" for s, e in result["scores"]))
    found = summary(result, len(radiance))
    if smk.params.align and result["significant"]:
        log.info("align_env: %s; applied", found)
        write_exr(smk.output.envmap, turn_envmap(given, result["degrees"]))
        # The test views' own maps come in the same convention: relight_real turns them alike.
        write_json(smk.output.rotation, {"degrees": result["degrees"]})
        return
    if smk.params.align:
        # Turning the map to a rotation the views do not single out would trade it for chance.
        log.info("align_env: the map as given is not significantly worse than the best rotation, so it is kept: %s",
                 found)
    elif result["clearly_worse"]:
        log.warning("%s/envmap.exr may be wrongly oriented: %s; set align_env: true for this capture to apply it",
                    smk.params.source, found)
    else:
        log.info("orientation as given is kept: %s", found)
    write_exr(smk.output.envmap, given)
    write_json(smk.output.rotation, {"degrees": 0.0})


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
