"""The views a selection chooses from: what each samples of the texels, from a capture or from poses alone."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.scene.cameras import Cameras
from freqbrdf.capture.observations import view_geometry
from freqbrdf.util.validation import check_shape
from freqbrdf.studies.views import mirror_light

__all__ = ["CandidateViews", "candidate_views", "capture_views", "capture_and_candidates"]


# --------------------------------------------------------------------------
# views and what they sample of the texels
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class CandidateViews:
    """What N views sample of T texels; the radiance only where the image exists.

    Attributes
    ----------
    weight : numpy.ndarray
        ``(T, N)``: cos(theta_o) where the view sees the texel, else 0.
    wo_local : numpy.ndarray
        ``(T, N, 3)``: unit direction to the camera in the texel frame.
    incoming : numpy.ndarray
        ``(T, N, 3)``: band-limited light along the mirror direction.
    names : tuple of str
        The N view names.
    radiance : numpy.ndarray
        ``(T, N, 3)``: outgoing radiance of the views in ``known``, 0 elsewhere.
    known : numpy.ndarray
        ``(N,)`` bool: views whose image (radiance) exists.
    """

    weight: np.ndarray
    wo_local: np.ndarray
    incoming: np.ndarray
    names: tuple[str, ...]
    radiance: np.ndarray
    known: np.ndarray

    def __post_init__(self) -> None:
        check_shape(np.asarray(self.weight), "weight", (None, None))
        n_tex, n_views = np.shape(self.weight)
        for name in ("wo_local", "incoming", "radiance"):
            check_shape(np.asarray(getattr(self, name)), name, (n_tex, n_views, 3))
        check_shape(np.asarray(self.known), "known", (n_views,))
        if len(self.names) != n_views:
            raise ValueError(f"names must name the {n_views} views, got {len(self.names)}")

    @classmethod
    def unseen(cls, weight: np.ndarray, wo_local: np.ndarray, incoming: np.ndarray,
               names: Sequence[str]) -> CandidateViews:
        """Views without images (poses only)."""
        return cls(weight, wo_local, incoming, tuple(names), np.zeros(np.shape(incoming)),
                   np.zeros(np.shape(weight)[1], bool))

    def __len__(self) -> int:
        return len(self.names)

    def __add__(self, other: CandidateViews) -> CandidateViews:
        """The views of both, ``self``'s first (same texels)."""
        return CandidateViews(*(np.concatenate([getattr(self, f), getattr(other, f)], axis=1)
                                for f in ("weight", "wo_local", "incoming")),
                              self.names + other.names, np.concatenate([self.radiance, other.radiance], axis=1),
                              np.concatenate([self.known, other.known]))


def candidate_views(position: np.ndarray, normal: np.ndarray, geometry: Mapping[str, np.ndarray],
                    occluded: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray], names: Sequence[str],
                    ray_offset: float) -> CandidateViews:
    """Views of T texels known from poses alone: facing, inside the image and unoccluded.

    Unlike extraction (:func:`freqbrdf.capture.observations.observe`) there is no mask
    and no image, so silhouette and occlusion-edge pixels are not dropped.

    Parameters
    ----------
    position, normal : numpy.ndarray
        ``(T, 3)`` world positions and unit normals.
    geometry : mapping
        :func:`freqbrdf.capture.observations.view_geometry` of the texels and the N cameras.
    occluded : callable
        ``occluded(origins, directions, lengths) -> (P,) bool``, e.g.
        :func:`freqbrdf.scene.raycast.occlusion_test` bound to the mesh.
    names : sequence of str
        The N view names.
    ray_offset : float
        Offset of the visibility rays along the normal (config ``observations.ray_offset``).
    """
    ti, ki = np.nonzero(geometry["candidate"])
    origins = position[ti] + ray_offset * normal[ti]
    wo = np.asarray(geometry["wo"][ti, ki], np.float64)
    camera = position[ti] + geometry["dist"][ti, ki, None] * wo
    blocked = occluded(origins, wo, np.linalg.norm(camera - origins, axis=1))
    seen_t, seen_k = ti[~blocked], ki[~blocked]
    weight = np.zeros(np.shape(geometry["candidate"]))
    weight[seen_t, seen_k] = geometry["cos_o"][seen_t, seen_k]
    return CandidateViews.unseen(weight, np.asarray(geometry["wo_local"], np.float64),
                                 np.asarray(geometry["incoming"], np.float64), names)


# --------------------------------------------------------------------------
# a capture and candidate poses (rule view_selection)
# --------------------------------------------------------------------------
def capture_views(obs: Observations, texels: np.ndarray, incoming_map: np.ndarray) -> CandidateViews:
    """A capture's K views (images known) on ``texels``, with the light of ``incoming_map``.

    Parameters
    ----------
    obs : Observations
        The capture, T texels x K views.
    texels : numpy.ndarray
        ``(t,)`` indices of the texels the selection averages over (:func:`freqbrdf.artefacts.sample_texels`).
    incoming_map : numpy.ndarray
        ``(H, W, 3)``: the environment band-limited at the a' of the views the selection ends with.
    """
    wo = np.asarray(obs.wo_local[texels], np.float64)
    return CandidateViews(np.asarray(obs.weight[texels], np.float64), wo,
                          mirror_light(obs.frame[texels], wo, incoming_map).astype(np.float64),
                          tuple(obs.meta["views"]), np.asarray(obs.radiance[texels], np.float64),
                          np.ones(wo.shape[1], bool))


def capture_and_candidates(obs: Observations, texels: np.ndarray, cameras: Cameras, incoming_map: np.ndarray,
                           occluded: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
                           ray_offset: float) -> CandidateViews:
    """`capture_views` followed by N candidate poses (no image).

    Parameters
    ----------
    obs, texels, incoming_map
        As in `capture_views`.
    cameras : Cameras
        The N candidate poses.
    occluded, ray_offset
        As in `candidate_views`.
    """
    sub = obs.texels.subset(texels)
    geometry = view_geometry(sub, cameras, incoming_map)
    return capture_views(obs, texels, incoming_map) + candidate_views(sub.position, sub.normal, geometry, occluded,
                                                                      cameras.names, ray_offset)
