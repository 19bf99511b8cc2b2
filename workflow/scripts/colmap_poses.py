"""Rule colmap_poses: camera poses of a training capture by pycolmap SfM, aligned to the reference frame."""

import shutil
import time
from pathlib import Path

import pycolmap

from freqbrdf.capture import sfm
from freqbrdf.capture.sfm_alignment import aligned_cameras, check_accuracy, pose_errors, reprojection_errors, summarise
from freqbrdf.capture.sfm_options import SfmOptions
from freqbrdf.scene.cameras import cameras_from_json, cameras_to_json
from freqbrdf.util.io import atomic_directory, atomic_path, read_json, write_json
from freqbrdf.util.logs import run_script


def main(smk, log):
    capture = Path(smk.input.capture)
    reference = cameras_from_json(read_json(capture / "cameras.json"), capture / "cameras.json")
    options = SfmOptions.from_config({**smk.params.colmap, "seed": smk.params.seed, "num_threads": smk.threads})
    gates = smk.params.gates
    with atomic_directory(smk.output[0]) as tmp:
        start = time.perf_counter()
        work = tmp / "work"
        try:
            reconstruction = sfm.reconstruct(capture, work, reference, options, log=log)
        finally:
            # COLMAP's own log is the first thing to read when registration fails.
            if (work / "colmap.log").exists():
                shutil.copy(work / "colmap.log", Path(smk.log[0]).with_suffix(".colmap.log"))
        # SfM only scored (no estimate uses its poses) keeps what it found, with a warning
        scored_only = None if smk.params.poses_used else log
        registered = sfm.check_registration(reconstruction.num_reg_images(), len(reference),
                                            gates["min_registered_fraction"], log=scored_only)
        cameras, similarity = aligned_cameras(reconstruction, reference, seed=options.seed)
        errors = pose_errors(cameras, reference, reprojection_errors(reconstruction))
        summary = summarise(errors, len(reference))
        log.info(
            "%d of %d views registered; median rotation error %.3f deg, median centre error %.3f%%, "
            "mean reprojection error %.3f px (%.1f s)",
            summary["registered"], summary["n_views"], summary["median_rotation_error_deg"],
            100 * summary["median_centre_error_rel"], summary["mean_reprojection_error_px"],
            time.perf_counter() - start,
        )
        log.info("per-view pose errors:\n%s", errors.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
        with atomic_path(tmp / "pose_errors.tsv") as f:
            errors.to_csv(f, sep="\t", index=False, float_format="%.6g")
        accurate = check_accuracy(summary, gates["max_median_rotation_deg"], gates["max_median_centre_error"],
                                  log=scored_only)
        summary["within_limits"] = registered and accurate
        write_json(tmp / "summary.json", summary)

        # The COLMAP model, moved into the reference frame, next to the cameras the observations use.
        reconstruction.transform(pycolmap.Sim3d(similarity[:3, :]))
        (tmp / "model").mkdir()
        reconstruction.write(tmp / "model")
        write_json(tmp / "cameras.json", cameras_to_json(cameras))
        shutil.rmtree(work)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
