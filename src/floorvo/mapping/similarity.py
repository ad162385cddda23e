"""Content-based image similarity of two floor frames (paper 003, section 3.1).

Paper 003 (Cao et al., J. Robotics 2017) matches two frames i and j in three steps:

1. **Overlap region extraction** (3.1.1): matched feature points give the rotation and
   translation between the frames (eq. 5, ``x_i = cos(th) x_j - sin(th) y_j + dx``,
   ``y_i = sin(th) x_j + cos(th) y_j + dy``); frame j is rotated and translated onto frame
   i and the overlap mask is the set of pixels covered by both. The paper keeps only
   "ceiling points" by checking that the segment joining two matched points has the same
   length in both frames (eqs. 17-19: points at equal height keep their distances). On a
   floor every texture point is at the same height, so the same length check is used as
   the consistency test of the two-point RANSAC hypotheses: it removes mismatched
   features instead of wall points.
2. **Overlap region rebuild by sub-block matching** (3.1.2): the overlap region of frame
   j is cut into equal sub-blocks; each is searched in frame i's overlap region for the
   smallest sum of absolute differences (eq. 20), which gives its displacement (dx_k, dy_k).
   The **mismatched sub-block check** (eqs. 21-22) deletes a sub-block whose displacement
   exceeds the threshold of a small affine (rotation + translation) model,
   ``|dx_k| <= T_x + T_th |y_k|``, ``|dy_k| <= T_y + T_th |x_k|`` with (x_k, y_k) the
   sub-block centre relative to the image centre.
3. **Similarity** (3.1.3, eq. 23): ``S = N * r``, the number of matched sub-blocks times the
   correlation coefficient between the rebuilt overlap region of frame j and the overlap
   region of frame i.

**The wall-distortion part of the paper (section 2.3, eqs. 6-16, and the wall terms of eq.
21) does not apply to floor images**: a camera looking straight down at a plane sees only
the rotation and translation of eq. (5) (the paper's own ceiling case, eqs. 2-4). It is
left out; after the rigid alignment the sub-block displacements of a correct match are
sub-pixel, and the sub-block rebuild serves as the mismatch check and as a sub-pixel
refinement of the rigid fit (the matched sub-blocks are correspondences of their own).

Pixel conventions: OpenCV ``(u, v)`` = (column, row). A rigid map ``(R, t)`` in pixels sends
a pixel of frame j to frame i: ``p_i = R p_j + t``, ``R`` (2, 2), ``t`` (2,).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, param
from floorvo.geometry import rigid_fit
from floorvo.imaging import illumination_corrected, to_uint8_contrast
from floorvo.matching import match_ratio

__all__ = [
    "SimilarityConfig",
    "Features",
    "RigidFit",
    "Similarity",
    "prepare_image",
    "FramePreparer",
    "detect_features",
    "match_descriptors",
    "ransac_rigid",
    "fit_features",
    "downscale",
    "content_similarity",
    "frame_similarity",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SimilarityConfig(Config):
    """Parameters of the content-based matching (section 3.1 of paper 003).

    ``n_features``: ORB keypoints per frame (binary descriptors: matching and the bag of
    words both use Hamming distance; the paper used SURF, which is not free in OpenCV).
    ``ratio``: Lowe ratio test of descriptor matches. ``ransac_iters``, ``ransac_tol_px``:
    two-point RANSAC of the rigid fit (eq. 5); ``length_tol``: relative tolerance of the
    connect-line length check (eqs. 17-19). ``min_inliers``: fewer inliers -> no overlap.
    ``sim_scale``: the sub-block stage runs on the frames resized by this factor.
    ``block_px``: sub-block side at that scale; ``search_px``: SAD search radius (eq. 20).
    ``thresh_t_px`` / ``thresh_rot_rad``: translation and rotation thresholds of the
    mismatched sub-block check (eq. 22).
    """

    config_name = "similarity"

    n_features: int = param(600, min=50, doc="ORB keypoints per frame")
    fast_threshold: int = param(10, min=1, max=100, doc="FAST threshold of the ORB detector")
    ratio: float = param(0.8, gt=0, max=1, doc="Lowe ratio test of descriptor matches")
    ransac_iters: int = param(200, min=10, doc="two-point RANSAC iterations of the rigid fit (eq. 5)")
    ransac_tol_px: float = param(2.0, unit="px", gt=0, doc="RANSAC inlier tolerance")
    length_tol: float = param(0.03, gt=0, lt=1, doc="relative tolerance of the connect-line length check (eqs. 17-19)")
    min_inliers: int = param(12, min=3, doc="fewer inliers: no overlap")
    sim_scale: float = param(0.5, min=0.1, max=1.0, doc="the sub-block stage runs on frames resized by this factor")
    block_px: int = param(12, unit="px", min=4, max=128, doc="sub-block side at sim_scale")
    search_px: int = param(3, unit="px", min=1, max=16, doc="SAD search radius of a sub-block (eq. 20)")
    thresh_t_px: float = param(
        1.0, unit="px", min=0, doc="translation threshold of the mismatched sub-block check (eq. 22)"
    )
    thresh_rot_rad: float = param(
        0.004, unit="rad", min=0, doc="rotation threshold of the mismatched sub-block check (eq. 22)"
    )


@dataclass(frozen=True)
class Features:
    """Keypoints of one frame: ``xy_px`` (N, 2) float32 (u, v) and ``desc`` (N, 32) uint8 ORB."""

    xy_px: np.ndarray
    desc: np.ndarray

    def __len__(self) -> int:
        return int(len(self.xy_px))


@dataclass(frozen=True)
class RigidFit:
    """Rigid map of pixels of frame j onto frame i (eq. 5): ``p_i = R p_j + t``.

    ``ok`` is false when no fit was found; ``reason`` says why.
    """

    ok: bool
    R: np.ndarray = field(default_factory=lambda: np.eye(2))
    t_px: np.ndarray = field(default_factory=lambda: np.zeros(2))
    n_matches: int = 0
    n_inliers: int = 0
    reason: str = ""

    @property
    def theta_rad(self) -> float:
        return float(np.arctan2(self.R[1, 0], self.R[0, 0]))

    def matrix(self) -> np.ndarray:
        """2x3 affine matrix for ``cv2.warpAffine``."""
        return np.hstack([self.R, self.t_px.reshape(2, 1)])


@dataclass(frozen=True)
class Similarity:
    """Result of :func:`content_similarity`.

    ``value``: eq. (23), matched sub-blocks x correlation coefficient (0 when there is no
    overlap). ``n_blocks``: matched sub-blocks; ``n_blocks_overlap``: sub-blocks in the
    overlap region; ``corr``: correlation coefficient; ``fit``: the rigid map j -> i
    (refined by the matched sub-blocks when ``refine``), in full-resolution pixels.
    """

    value: float
    n_blocks: int
    n_blocks_overlap: int
    corr: float
    fit: RigidFit
    reason: str = ""

    @property
    def block_fraction(self) -> float:
        return self.n_blocks / self.n_blocks_overlap if self.n_blocks_overlap else 0.0


# --------------------------------------------------------------------------- images
def prepare_image(image: np.ndarray, flatfield: np.ndarray | None = None) -> np.ndarray:
    """uint8 (H, W) frame with the LED falloff divided out and the contrast normalised.

    Uses the flat-field frame when given, a wide blur of the frame itself otherwise
    (:func:`floorvo.imaging.illumination_corrected`, the blur made on an 8x smaller copy).
    """
    img = np.asarray(image)
    if img.ndim != 2:
        raise ValueError(f"prepare_image: need a (H, W) mono image, got shape {img.shape}")
    return to_uint8_contrast(illumination_corrected(img, flatfield, blur_downscale=8))


class FramePreparer:
    """Raw (H, W) frames of ``camera`` -> prepared uint8 frames (:func:`prepare_image`, with the
    camera's ``flatfield``) in the pixels of the ideal pinhole ``pinhole`` (a keyframe map's:
    :meth:`~floorvo.camera.CameraModel.square_pinhole` of the map's camera).

    The rigid fit of eq. (5), its length check (eqs. 17-19) and the sub-block warps assume
    that a floor point's image moves rigidly, which holds only in an ideal pinhole with square
    pixels; and :func:`floorvo.mapping.keyframes.fit_to_T_i_j` converts a fit to mm with one
    camera's intrinsics. A frame of a lens with distortion, of pixels with ``fx != fy``, or of
    another camera than the map's (another principal point or focal length, a recalibration)
    is therefore resampled into the map's pinhole first (:meth:`CameraModel.rectify_maps`, made
    once): at k1 = -0.3, or fy = 1.02 fx with the frame turned, or a query camera whose
    principal point was 20 px from the map's, fixes were reported 1.3 to 11 times issue 14's
    bound off. A camera that is the pinhole itself is not resampled.
    """

    def __init__(self, camera: CameraModel, pinhole: CameraModel, flatfield: np.ndarray | None = None):
        self.camera, self.pinhole, self.flatfield = camera, pinhole, flatfield
        self.maps = camera.rectify_maps(pinhole)

    def __call__(self, image: np.ndarray, scale: float = 1.0) -> np.ndarray:
        """The prepared frame; ``scale``: enlarged by it about the pinhole's principal point (a
        frame taken at ``scale`` x the map's camera height, seen as at the map's: a floor point's
        image lies ``f r / h`` px from the principal point)."""
        p = prepare_image(image, self.flatfield)
        if self.maps is not None:
            p = cv2.remap(p, *self.maps, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if scale != 1.0:
            cx, cy = self.pinhole.cx_px, self.pinhole.cy_px
            A = np.array([[scale, 0.0, (1.0 - scale) * cx], [0.0, scale, (1.0 - scale) * cy]])
            p = cv2.warpAffine(p, A, (p.shape[1], p.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return p


def downscale(image_u8: np.ndarray, scale: float) -> np.ndarray:
    """Resize by ``scale`` (area averaging); the identity for scale 1."""
    if scale == 1.0:
        return image_u8
    h, w = image_u8.shape
    return cv2.resize(image_u8, (max(1, round(w * scale)), max(1, round(h * scale))), interpolation=cv2.INTER_AREA)


_ORB_CACHE: dict[tuple[int, int], cv2.ORB] = {}


def detect_features(image_u8: np.ndarray, cfg: SimilarityConfig) -> Features:
    """ORB keypoints and descriptors of a prepared uint8 frame."""
    key = (cfg.n_features, cfg.fast_threshold)
    orb = _ORB_CACHE.get(key)
    if orb is None:
        orb = cv2.ORB.create(
            nfeatures=cfg.n_features,
            scaleFactor=1.2,
            nlevels=2,
            edgeThreshold=19,
            patchSize=19,
            fastThreshold=cfg.fast_threshold,
        )
        _ORB_CACHE[key] = orb
    kps, desc = orb.detectAndCompute(image_u8, None)
    if desc is None or not kps:
        return Features(np.zeros((0, 2), np.float32), np.zeros((0, 32), np.uint8))
    return Features(np.array([k.pt for k in kps], dtype=np.float32), desc)


def match_descriptors(fa: Features, fb: Features, ratio: float) -> np.ndarray:
    """(M, 2) index pairs (i in ``fa``, j in ``fb``) passing the ratio test, one per j.

    One keypoint of frame i may not take two keypoints of frame j: the pair of the lowest j
    is kept (:func:`floorvo.matching.ratio_test`, ``unique="first"``).
    """
    if len(fa) < 2 or len(fb) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    m = match_ratio(fb.desc, fa.desc, ratio, unique="first")
    return m.idx[:, ::-1].copy()


def ransac_rigid(
    src: np.ndarray, dst: np.ndarray, cfg: SimilarityConfig, rng: np.random.Generator | None = None
) -> RigidFit:
    """Rigid fit ``dst = R src + t`` (eq. 5) by two-point RANSAC.

    A hypothesis is kept only if its two points pass the connect-line length check of
    eqs. (17)-(19) (equal-height points keep their distance; on the floor every point
    does, so a changed length means a mismatch). The consensus set is refitted in closed
    form (:func:`floorvo.geometry.rigid_fit`). ``src``, ``dst``: (N, 2) pixels.
    """
    n = len(src)
    if n < max(2, cfg.min_inliers):
        return RigidFit(False, n_matches=n, reason=f"{n} feature matches < {cfg.min_inliers}")
    rng = rng or np.random.default_rng(0)
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    a = rng.integers(0, n, cfg.ransac_iters)
    b = rng.integers(0, n, cfg.ransac_iters)
    vs, vd = src[b] - src[a], dst[b] - dst[a]
    ls, ld = np.linalg.norm(vs, axis=1), np.linalg.norm(vd, axis=1)
    # Eqs. (17)-(19): the segment joining two points on the plane keeps its length.
    keep = (ls > 10.0) & (np.abs(ls - ld) <= cfg.length_tol * ls + 0.5)
    if not keep.any():
        return RigidFit(False, n_matches=n, reason="no pair of matches keeps its length (eqs. 17-19)")
    a, b, vs, vd = a[keep], b[keep], vs[keep], vd[keep]
    th = np.arctan2(vd[:, 1], vd[:, 0]) - np.arctan2(vs[:, 1], vs[:, 0])
    c, s = np.cos(th), np.sin(th)
    # Eq. (5): dst = R(th) src + t, t from the first point of the pair.
    tx = dst[a, 0] - (c * src[a, 0] - s * src[a, 1])
    ty = dst[a, 1] - (s * src[a, 0] + c * src[a, 1])
    px = c[:, None] * src[None, :, 0] - s[:, None] * src[None, :, 1] + tx[:, None]
    py = s[:, None] * src[None, :, 0] + c[:, None] * src[None, :, 1] + ty[:, None]
    err2 = (px - dst[None, :, 0]) ** 2 + (py - dst[None, :, 1]) ** 2
    inl = err2 <= cfg.ransac_tol_px**2
    best = int(np.argmax(inl.sum(axis=1)))
    mask = inl[best]
    for _ in range(2):
        if mask.sum() < 2:
            break
        R, t = rigid_fit(src[mask], dst[mask])
        res = np.linalg.norm(src @ R.T + t - dst, axis=1)
        mask = res <= cfg.ransac_tol_px
    k = int(mask.sum())
    if k < cfg.min_inliers:
        return RigidFit(False, n_matches=n, n_inliers=k, reason=f"{k} rigid inliers < {cfg.min_inliers}")
    R, t = rigid_fit(src[mask], dst[mask])
    return RigidFit(True, R, t, n_matches=n, n_inliers=k)


def fit_features(fi: Features, fj: Features, cfg: SimilarityConfig, rng: np.random.Generator | None = None) -> RigidFit:
    """Match the features of frames i and j and fit eq. (5): pixels of j -> pixels of i."""
    pairs = match_descriptors(fi, fj, cfg.ratio)
    if len(pairs) == 0:
        return RigidFit(False, reason="no feature matches")
    return ransac_rigid(fj.xy_px[pairs[:, 1]], fi.xy_px[pairs[:, 0]], cfg, rng)


# --------------------------------------------------------------------------- sub-blocks
def _scale_fit(fit: RigidFit, s: float) -> tuple[np.ndarray, np.ndarray]:
    """The rigid map in pixels of images resized by ``s`` (pixel centres: u' = s (u + 0.5) - 0.5)."""
    off = 0.5 * (s - 1.0)
    t = s * fit.t_px + off * (np.ones(2) - fit.R @ np.ones(2))
    return fit.R, t


def _unscale_points(p: np.ndarray, s: float) -> np.ndarray:
    return (p + 0.5) / s - 0.5


def content_similarity(
    img_i: np.ndarray,
    img_j: np.ndarray,
    fit: RigidFit,
    cfg: SimilarityConfig,
    *,
    refine: bool = True,
) -> Similarity:
    """Eqs. (20)-(23) of paper 003 on two prepared frames at the similarity scale.

    ``img_i``, ``img_j``: uint8 (h, w) frames already resized by ``cfg.sim_scale``
    (:func:`downscale`); ``fit``: the rigid map of full-resolution pixels of j onto i (eq.
    5). Frame j is rotated and translated onto frame i (overlap region extraction,
    3.1.1); each sub-block of the overlap is searched in frame i by SAD (eq. 20); sub-blocks
    failing the affine threshold (eq. 22) are deleted; the similarity is eq. (23).
    With ``refine``, the matched sub-blocks refine the rigid fit (sub-pixel SAD minimum).
    """
    if not fit.ok:
        return Similarity(0.0, 0, 0, 0.0, fit, fit.reason)
    s = cfg.sim_scale
    h, w = img_i.shape
    R, t = _scale_fit(fit, s)
    M = np.hstack([R, t.reshape(2, 1)])
    A = img_i.astype(np.float32)
    Bw = cv2.warpAffine(img_j.astype(np.float32), M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    cover = cv2.warpAffine(np.ones(img_j.shape, np.uint8), M, (w, h), flags=cv2.INTER_NEAREST, borderValue=0)
    # Overlap mask (Fig. 4f): pixels covered by both frames, shrunk so that every searched
    # position of a sub-block stays inside the overlap.
    r = cfg.search_px
    kernel = np.ones((2 * r + 3, 2 * r + 3), np.uint8)
    inner = cv2.erode(cover, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    inner[: r + 1, :] = 0
    inner[h - r - 1 :, :] = 0
    inner[:, : r + 1] = 0
    inner[:, w - r - 1 :] = 0
    b = cfg.block_px
    nby, nbx = h // b, w // b
    H, W = nby * b, nbx * b
    block_ok = inner[:H, :W].reshape(nby, b, nbx, b).min(axis=(1, 3)) > 0
    n_overlap = int(block_ok.sum())
    if n_overlap == 0:
        return Similarity(0.0, 0, 0, 0.0, fit, "no sub-block inside the overlap region")
    # Eq. (20): SAD of each sub-block of frame j's overlap region at every displacement
    # (dx, dy) in frame i's overlap region, |dx|, |dy| <= search_px.
    Bc = Bw[:H, :W]
    Apad = cv2.copyMakeBorder(A, r, r, r, r, cv2.BORDER_REPLICATE)
    n_sh = 2 * r + 1
    sad = np.empty((n_sh, n_sh, nby, nbx), np.float32)
    for iy in range(n_sh):
        for ix in range(n_sh):
            d = cv2.absdiff(Apad[iy : iy + H, ix : ix + W], Bc)
            sad[iy, ix] = cv2.resize(d, (nbx, nby), interpolation=cv2.INTER_AREA)
    flat = sad.reshape(n_sh * n_sh, nby, nbx)
    k = np.argmin(flat, axis=0)
    dy_i, dx_i = np.divmod(k, n_sh)
    dx = (dx_i - r).astype(np.float64)
    dy = (dy_i - r).astype(np.float64)
    # Eqs. (21)-(22): a small residual rotation d_th and translation (d_x, d_y) move the
    # sub-block at (x_k, y_k) (from the image centre) by (d_x - d_th y_k, d_y + d_th x_k);
    # a displacement beyond T_x + T_th |y_k| or T_y + T_th |x_k| marks a mismatched sub-block.
    yc = (np.arange(nby) + 0.5) * b - 0.5 - (h - 1) / 2.0
    xc = (np.arange(nbx) + 0.5) * b - 0.5 - (w - 1) / 2.0
    XC, YC = np.meshgrid(xc, yc)
    thr_x = cfg.thresh_t_px + cfg.thresh_rot_rad * np.abs(YC)
    thr_y = cfg.thresh_t_px + cfg.thresh_rot_rad * np.abs(XC)
    matched = block_ok & (np.abs(dx) <= thr_x) & (np.abs(dy) <= thr_y)
    n = int(matched.sum())
    if n == 0:
        return Similarity(0.0, 0, n_overlap, 0.0, fit, "every sub-block failed the mismatch check (eq. 22)")
    # Rebuild the overlap region of frame j (Fig. 7): each matched sub-block is moved to
    # its SAD position; compare it with frame i there (eq. 23).
    iy_b, ix_b = np.nonzero(matched)
    rows = iy_b[:, None] * b + np.arange(b)[None, :]  # (n, b)
    cols = ix_b[:, None] * b + np.arange(b)[None, :]
    blk_j = Bc[rows[:, :, None], cols[:, None, :]]
    blk_i = Apad[
        (rows + r + dy[iy_b, ix_b].astype(int)[:, None])[:, :, None],
        (cols + r + dx[iy_b, ix_b].astype(int)[:, None])[:, None, :],
    ]
    xj = blk_j.astype(np.float64).ravel()
    xi = blk_i.astype(np.float64).ravel()
    xj -= xj.mean()
    xi -= xi.mean()
    den = np.sqrt((xj @ xj) * (xi @ xi))
    corr = float(xj @ xi / den) if den > 0 else 0.0
    value = n * max(corr, 0.0)  # Eq. (23): S = N * r
    out_fit = fit
    if refine and n >= 6:
        out_fit = _refine_fit(fit, flat, iy_b, ix_b, dx, dy, r, XC, YC, M, s, w, h)
    return Similarity(float(value), n, n_overlap, corr, out_fit)


def _subpixel(c_m: np.ndarray, c_0: np.ndarray, c_p: np.ndarray) -> np.ndarray:
    den = c_m - 2 * c_0 + c_p
    off = np.where(den > 1e-9, 0.5 * (c_m - c_p) / np.where(den > 1e-9, den, 1.0), 0.0)
    return np.clip(off, -0.5, 0.5)


def _refine_fit(fit, flat, iy_b, ix_b, dx, dy, r, XC, YC, M, s, w, h) -> RigidFit:
    """Refit eq. (5) on the matched sub-blocks: centre in frame j <-> SAD position in frame i."""
    n_sh = 2 * r + 1
    sad = flat.reshape(n_sh, n_sh, *flat.shape[1:])
    kx = (dx[iy_b, ix_b] + r).astype(int)
    ky = (dy[iy_b, ix_b] + r).astype(int)
    inner = (kx > 0) & (kx < n_sh - 1) & (ky > 0) & (ky < n_sh - 1)
    if inner.sum() < 6:
        return fit
    iy_b, ix_b, kx, ky = iy_b[inner], ix_b[inner], kx[inner], ky[inner]
    c0 = sad[ky, kx, iy_b, ix_b]
    ox = _subpixel(sad[ky, kx - 1, iy_b, ix_b], c0, sad[ky, kx + 1, iy_b, ix_b])
    oy = _subpixel(sad[ky - 1, kx, iy_b, ix_b], c0, sad[ky + 1, kx, iy_b, ix_b])
    cx = XC[iy_b, ix_b] + (w - 1) / 2.0
    cy = YC[iy_b, ix_b] + (h - 1) / 2.0
    p_i = np.stack([cx + kx - r + ox, cy + ky - r + oy], axis=1)  # where the block's content lies in frame i
    # The block's content in frame j: invert the warp (p_i_nominal = R p_j + t).
    Rm, tm = M[:, :2], M[:, 2]
    p_j = (np.stack([cx, cy], axis=1) - tm) @ Rm  # R^T (p - t)
    R2, t2 = rigid_fit(_unscale_points(p_j, s), _unscale_points(p_i, s))
    return RigidFit(True, R2, t2, fit.n_matches, fit.n_inliers, fit.reason)


def frame_similarity(
    img_i_small: np.ndarray,
    feats_i: Features,
    img_j_small: np.ndarray,
    feats_j: Features,
    cfg: SimilarityConfig,
    *,
    refine: bool = True,
    rng: np.random.Generator | None = None,
) -> Similarity:
    """Similarity of frames i and j (section 3.1): feature rigid fit, then eqs. (20)-(23)."""
    fit = fit_features(feats_i, feats_j, cfg, rng)
    return content_similarity(img_i_small, img_j_small, fit, cfg, refine=refine)
