"""How well the SfM's own observations can place the cameras at all: its poses against the floor
that its tracks allow.

For each capture (``object/env`` of a results tree whose rule ``colmap_poses`` has run), reads
that run's COLMAP model (its tracks, 2D observations and intrinsics held fixed) and the
renderer's cameras, and reports the median rotation error after the similarity alignment and the
median relative rotation error (no alignment in it; `freqbrdf.capture.sfm_alignment`) of:

- ``sfm``: the model as the run left it, and its mean reprojection error;
- ``from truth``: the poses set to the true ones, the points refitted with them held, then one
  full bundle adjustment. Where it ends is where least squares puts the cameras given these
  observations: if it returns to ``sfm``'s errors, the mapper is not at fault, the observations
  are; the reprojection errors at the truth and after say how little the data prefer it;
- ``noise <sigma>``: every observation replaced by its point's true projection (points refitted on
  the true poses) plus seeded Gaussian noise of ``sigma`` pixels, then a full bundle adjustment
  from the truth: the error these tracks give with noise alone, the floor of any SIFT setting
  that keeps tracks like these.

    python bench/sfm_floor.py --results DIR --captures sphere/sky bunny/lobby [--sigma 0.3] [--seeds 3]

One thread; writes ``<out>/sfm_floor.tsv``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import pycolmap

from freqbrdf import layout
from freqbrdf.capture.sfm_alignment import aligned_cameras, pose_errors
from freqbrdf.scene.cameras import Cameras, cameras_from_json
from freqbrdf.util.io import read_json

REPO = Path(__file__).resolve().parents[1]


def adjust(reconstruction: pycolmap.Reconstruction, poses: bool = True) -> None:
    """Bundle adjustment with the intrinsics held (as the pipeline's SfM holds them), to convergence."""
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = options.refine_principal_point = options.refine_extra_params = False
    options.refine_rig_from_world = poses
    options.print_summary = False
    solver = options.ceres.solver_options
    solver.num_threads = 1
    solver.function_tolerance = solver.gradient_tolerance = solver.parameter_tolerance = 1e-12
    solver.max_num_iterations = 500
    pycolmap.bundle_adjustment(reconstruction, options)


def set_true_poses(reconstruction: pycolmap.Reconstruction, reference: Cameras) -> None:
    """Each registered view's pose set to the renderer's, then the points refitted with the poses held."""
    index = {name: i for i, name in enumerate(reference.names)}
    for image_id in reconstruction.reg_image_ids():
        image = reconstruction.image(image_id)
        world_to_camera = reference.world_to_camera[index[Path(image.name).stem]]
        reconstruction.frames[image.frame_id].rig_from_world = pycolmap.Rigid3d(
            pycolmap.Rotation3d(world_to_camera[:3, :3]), world_to_camera[:3, 3])
    adjust(reconstruction, poses=False)


def add_noise(reconstruction: pycolmap.Reconstruction, sigma: float, rng: np.random.Generator) -> None:
    """Every observation of a track moved to its point's projection plus N(0, sigma^2) pixels per axis."""
    for image_id in reconstruction.reg_image_ids():
        image = reconstruction.image(image_id)
        for k, point in enumerate(image.points2D):
            if point.has_point3D():
                xy = image.project_point(reconstruction.points3D[point.point3D_id].xyz)
                image.points2D[k].xy = np.asarray(xy) + rng.normal(0.0, sigma, 2)


def errors(reconstruction: pycolmap.Reconstruction, reference: Cameras) -> dict[str, float]:
    """Median aligned and relative rotation errors (degrees) and the mean reprojection error (pixels)."""
    cameras, _ = aligned_cameras(reconstruction, reference)
    table = pose_errors(cameras, reference)
    return {"rotation_deg": float(table.rotation_error_deg.median()),
            "relative_rotation_deg": float(table.relative_rotation_error_deg.median()),
            "reprojection_px": float(reconstruction.compute_mean_reprojection_error())}


def capture_rows(results: Path, capture: str, sigma: float, seeds: int) -> list[dict]:
    """The rows of one capture: sfm, from truth (at the truth and after), noise per seed."""
    obj, env = capture.split("/")
    train = layout.located(layout.CAPTURE, results, object=obj, env=env, split="train")
    reference = cameras_from_json(read_json(train / "cameras.json"), train / "cameras.json")
    model = layout.located(layout.COLMAP_POSES, results, object=obj, env=env) / "model"
    if not model.is_dir():
        raise FileNotFoundError(f"{model}: no SfM model (run rule colmap_poses for {capture})")
    reconstruction = pycolmap.Reconstruction(str(model))
    points = len(reconstruction.points3D)
    track = np.mean([p.track.length() for p in reconstruction.points3D.values()])
    rows = [{"case": "sfm"} | errors(reconstruction, reference)]
    truth = pycolmap.Reconstruction(str(model))
    set_true_poses(truth, reference)
    at_truth = float(truth.compute_mean_reprojection_error())
    adjust(truth)
    rows.append({"case": "from truth", "reprojection_at_truth_px": at_truth} | errors(truth, reference))
    for seed in range(seeds):
        noisy = pycolmap.Reconstruction(str(model))
        set_true_poses(noisy, reference)
        add_noise(noisy, sigma, np.random.default_rng(seed))
        adjust(noisy)
        rows.append({"case": f"noise {sigma:g}", "seed": seed} | errors(noisy, reference))
    return [{"capture": capture, "points": points, "mean_track": track} | row for row in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, required=True, help="a results tree with the captures' SfM models")
    parser.add_argument("--captures", nargs="+", required=True, help="object/env")
    parser.add_argument("--sigma", type=float, default=0.3, help="pixels of noise on the true projections")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "out")
    args = parser.parse_args()
    rows = [row for capture in args.captures for row in capture_rows(args.results, capture, args.sigma, args.seeds)]
    table = pd.DataFrame(rows)
    print(table.to_string(index=False, float_format="%.3f"))
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "sfm_floor.tsv", sep="\t", index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
