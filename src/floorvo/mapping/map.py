"""The keyframe global map (paper 003, section 3.2): build, save, load.

A map holds the keyframes (prepared images at the similarity scale, ORB keypoints and
descriptors), their global poses ``T_world_kf`` (mm, eq. 24), the bag-of-words vocabulary
for retrieval, the camera model, the camera height and every parameter used. Images and
keypoints are in the pixels of the camera's ideal square pinhole (:attr:`GlobalMap.pinhole`:
a distorted lens's frames, or frames of pixels with ``fx != fy``, are resampled into it,
:class:`~floorvo.mapping.similarity.FramePreparer`), where the floor moves rigidly.

On disk a map is a folder::

    MAP/map.json        schema_version, format, camera, height_mm, parameters, keyframe
                        frame indices, timestamps and poses (T_world_kf, mm), pose_source
                        ("groundtruth" or "chain"), chain_vs_groundtruth, its own
                        content_sha256, and the sha256 of:
    MAP/keyframes.npz   images (K, h, w) uint8, kp_xy_px (M, 2) float32, kp_desc (M, 32)
                        uint8, kp_offsets (K + 1,) int64, vocab_words (V, 32) uint8,
                        vocab_idf (V,) float32, T_world_kf (K, 4, 4) float64

Both files are written atomically, the arrays first; ``map.json`` names the arrays'
checksum and carries one of its own content, so a map whose files do not belong together,
or whose ``map.json`` was edited (a camera with another focal length), is refused on loading.
Schema version 1 (before the frames were resampled into the pinhole) is read only for a
camera that is its own pinhole (no distortion, ``fx == fy``), where nothing changed.
"""

from __future__ import annotations

import hashlib
import io
import logging
import os
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorvo.camera import CAMERA_HEIGHT_RANGE_MM, CameraModel
from floorvo.config import MAX_SEED, Config, build, from_overrides, param, to_plain
from floorvo.errors import ConfigError, FloorbenchError, SequenceError, shown
from floorvo.geometry import T_world_cam_down, invert_T
from floorvo.io import (
    atomic_write_bytes,
    atomic_write_json,
    ensure_writable_dir,
    file_name_problem,
    json_sha256,
    read_json,
    read_npz,
)
from floorvo.locking import locks_folder
from floorvo.mapping.keyframes import KeyframeConfig, chain_poses, extract_keyframes
from floorvo.mapping.retrieval import BinaryVocabulary, KeyframeIndex, VoteIndex
from floorvo.mapping.similarity import Features, FramePreparer, SimilarityConfig, detect_features, downscale
from floorvo.sequence import Sequence

__all__ = [
    "MAP_SCHEMA_VERSION",
    "MapConfig",
    "MapFile",
    "GlobalMap",
    "build_map",
    "build_map_from_images",
    "load_map",
    "save_map",
]

log = logging.getLogger(__name__)

#: Version of the map folder format :func:`save_map` writes; :func:`load_map` refuses any other
#: (but 1, for a camera that is its own square pinhole: :data:`MAP_SCHEMA_VERSIONS_READ`).
MAP_SCHEMA_VERSION = 2
#: 1: keyframe images and keypoints in the camera's own pixels (a distorted lens's, or ``fx !=
#: fy``); 2: in its square pinhole's (:attr:`GlobalMap.pinhole`). The two differ only where the
#: camera is not its own pinhole.
MAP_SCHEMA_VERSIONS_READ = (1, 2)
MAP_FORMAT = "floorbench-keyframe-map"
#: Values of ``MapConfig.poses``.
POSE_SOURCES = ("groundtruth", "chain")


@dataclass(frozen=True)
class MapConfig(Config):
    """All map parameters: similarity (section 3.1), keyframes (3.2), vocabulary size.

    ``poses``: ``"groundtruth"`` takes each keyframe's ground-truth pose when the mapping
    sequence has one (a map is built on a surveyed run, so the surveyed poses are the better
    map; the eq. (24) chain is still computed and its disagreement recorded), and falls back
    to the chain otherwise; ``"chain"`` always uses eq. (24).
    """

    config_name = "map"

    similarity: SimilarityConfig = param(default_factory=SimilarityConfig)
    keyframes: KeyframeConfig = param(default_factory=KeyframeConfig)
    vocab_words: int = param(512, min=2, doc="words of the binary bag-of-words vocabulary")
    seed: int = param(0, min=0, max=MAX_SEED, doc="seeds the vocabulary and the LSH tables")
    poses: str = param("groundtruth", choices=POSE_SOURCES, doc="keyframe poses: surveyed, or chained by eq. (24)")

    @classmethod
    def from_overrides(cls, overrides: Mapping[str, Any] | None) -> MapConfig:
        """Build from ``{"similarity.block_px": "12", "keyframes.window": "50", "vocab_words": "512"}``."""
        return from_overrides(cls, overrides, "map", listed_by="floorvo list --config map")

    def to_dict(self) -> dict:
        return to_plain(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MapConfig:
        """From :meth:`to_dict`'s output (a map.json); maps written before ``poses`` existed chained."""
        return build(cls, {"poses": "chain", **d}, "map")


@dataclass
class GlobalMap:
    """Keyframes and their global poses. ``T_world_kf`` (K, 4, 4) mm; ``images`` (K, h, w)
    uint8 prepared frames at ``config.similarity.sim_scale``; ``features`` K keypoint sets
    in full-resolution pixels; ``frame_indices`` / ``timestamps_s`` of the keyframes in the
    mapping sequence."""

    camera: CameraModel
    height_mm: float
    config: MapConfig
    frame_indices: list[int]
    timestamps_s: np.ndarray
    T_world_kf: np.ndarray
    images: np.ndarray
    features: list[Features]
    vocab: BinaryVocabulary
    n_mapping_frames: int = 0
    source: str = ""
    #: ``"groundtruth"`` or ``"chain"`` (eq. 24): where ``T_world_kf`` came from.
    pose_source: str = "chain"
    #: When ground truth was at hand: the eq. (24) chain against it, ``{"max_mm", "rms_mm",
    #: "max_yaw_rad"}`` over the keyframes (a measure of the map's own drift); else empty.
    chain_vs_groundtruth: dict = field(default_factory=dict)
    _index: KeyframeIndex | None = field(default=None, repr=False)
    _vote_index: VoteIndex | None = field(default=None, repr=False)

    @property
    def n_keyframes(self) -> int:
        return len(self.frame_indices)

    @property
    def pinhole(self) -> CameraModel:
        """The ideal square pinhole (:meth:`CameraModel.square_pinhole` of :attr:`camera`) whose
        pixels ``images`` and ``features`` are in, and in which fits are converted to mm."""
        return self.camera.square_pinhole()

    @property
    def index(self) -> KeyframeIndex:
        if self._index is None:
            self._index = KeyframeIndex(self.vocab, [f.desc for f in self.features])
        return self._index

    @property
    def vote_index(self) -> VoteIndex:
        if self._vote_index is None:
            self._vote_index = VoteIndex([f.desc for f in self.features], seed=self.config.seed)
        return self._vote_index

    @property
    def keyframe_fraction(self) -> float:
        return self.n_keyframes / self.n_mapping_frames if self.n_mapping_frames else float("nan")


def build_map_from_images(
    get_image: Callable[[int], np.ndarray],
    n_frames: int,
    camera: CameraModel,
    height_mm: float,
    *,
    timestamps_s: np.ndarray | None = None,
    T_world_first: np.ndarray | None = None,
    T_world_frames: np.ndarray | None = None,
    flatfield: np.ndarray | None = None,
    config: MapConfig | None = None,
    source: str = "",
    on_progress: Callable[[int, int], None] | None = None,
) -> GlobalMap:
    """Build a map from frames ``get_image(0 .. n_frames - 1)`` (raw (H, W) images of ``camera``,
    resampled into its square pinhole: :class:`~floorvo.mapping.similarity.FramePreparer`).

    ``T_world_first``: pose of frame 0 (the map's world frame; default: downward camera at
    the origin with yaw 0 at ``height_mm``). ``T_world_frames``: (n_frames, 4, 4) ground-truth
    poses (mm) of the frames, NaN for a frame without one, or None; with ``config.poses ==
    "groundtruth"`` and a pose for every keyframe the keyframes take theirs (see
    :class:`MapConfig`); the chain is anchored at the first keyframe that has one (its own: a
    ground truth starting two frames late gave frame 0 frame 2's pose, and every keyframe and
    fix was 8 mm off, reported ok).
    """
    cfg = config or MapConfig()
    sc = cfg.similarity
    cache: OrderedDict[int, tuple[np.ndarray, Features]] = OrderedDict()
    cap = cfg.keyframes.window + 4
    prepare = FramePreparer(camera, camera.square_pinhole(), flatfield)

    def prepared(i: int) -> tuple[np.ndarray, Features]:
        if i in cache:
            cache.move_to_end(i)
            return cache[i]
        img = get_image(i)
        if img.shape != (camera.height_px, camera.width_px):
            raise SequenceError(
                f"frame {i}: size {img.shape[1]}x{img.shape[0]} differs from the camera's {camera.width_px}x{camera.height_px}"
            )
        p = prepare(img)
        val = (downscale(p, sc.sim_scale), detect_features(p, sc))
        cache[i] = val
        while len(cache) > cap:
            cache.popitem(last=False)
        return val

    res = extract_keyframes(
        lambda i: prepared(i)[0],
        lambda i: prepared(i)[1],
        n_frames,
        prepare.pinhole,
        height_mm,
        sc,
        cfg.keyframes,
        rng=np.random.default_rng(cfg.seed),
        on_progress=on_progress,
    )
    gt = None if T_world_frames is None else np.asarray(T_world_frames, float).reshape(-1, 4, 4)
    if gt is not None and len(gt) != n_frames:
        raise ValueError(f"T_world_frames has {len(gt)} poses for {n_frames} frames")
    kf = np.asarray(res.indices)
    has_gt = np.zeros(len(kf), bool) if gt is None else ~np.isnan(gt[kf]).any(axis=(1, 2))
    if T_world_first is not None:
        T0 = np.asarray(T_world_first, float)
    elif has_gt.any():
        j = int(np.argmax(has_gt))  # the first keyframe with a ground-truth pose anchors the chain there
        T0 = gt[kf[j]] @ invert_T(chain_poses(np.eye(4), res.T_kf_prev_kf)[j])  # type: ignore[index]
    else:
        if gt is not None:
            log.warning("map: no keyframe has a ground-truth pose: the chain starts at the origin")
        T0 = T_world_cam_down(0.0, 0.0, height_mm)
    T_chain = chain_poses(T0, res.T_kf_prev_kf)  # Eq. (24)
    pose_source, chain_vs_gt = "chain", {}
    T_world_kf = T_chain
    if gt is not None and has_gt.any():
        T_gt = gt[kf]
        C, G = T_chain[has_gt], T_gt[has_gt]
        d_mm = np.linalg.norm(C[:, :2, 3] - G[:, :2, 3], axis=1)
        d_yaw = np.abs(np.angle(np.exp(1j * (np.arctan2(C[:, 1, 0], C[:, 0, 0]) - np.arctan2(G[:, 1, 0], G[:, 0, 0])))))
        chain_vs_gt = {
            "max_mm": float(d_mm.max()),
            "rms_mm": float(np.sqrt(np.mean(d_mm**2))),
            "max_yaw_rad": float(d_yaw.max()),
        }
        log.info(
            "map: eq. (24) chain against ground truth: max %.3f mm, rms %.3f mm",
            chain_vs_gt["max_mm"],
            chain_vs_gt["rms_mm"],
        )
        if cfg.poses == "groundtruth" and has_gt.all():
            T_world_kf, pose_source = T_gt.copy(), "groundtruth"
    images = np.stack([prepared(i)[0] for i in res.indices])
    feats = [prepared(i)[1] for i in res.indices]
    vocab = BinaryVocabulary.train([f.desc for f in feats], n_words=cfg.vocab_words, seed=cfg.seed)
    ts = np.asarray(timestamps_s, float)[res.indices] if timestamps_s is not None else np.asarray(res.indices, float)
    log.info(
        "map: %d keyframes of %d frames (%.1f %%)", len(res.indices), n_frames, 100.0 * len(res.indices) / n_frames
    )
    return GlobalMap(
        camera,
        float(height_mm),
        cfg,
        list(map(int, res.indices)),
        ts,
        T_world_kf,
        images,
        feats,
        vocab,
        n_mapping_frames=int(n_frames),
        source=source,
        pose_source=pose_source,
        chain_vs_groundtruth=chain_vs_gt,
    )


def build_map(
    seq_path: str | os.PathLike,
    config: MapConfig | None = None,
    *,
    on_progress: Callable[[int, int], None] | None = None,
) -> GlobalMap:
    """Build a map from a sequence folder. With ground truth for every frame, the keyframes
    take their ground-truth poses (``config.poses == "groundtruth"``, the default) or the
    eq. (24) chain starts at the first frame's (``"chain"``), so map and ground truth share
    the world frame; without ground truth the chain starts at the origin."""
    seq = Sequence.open(seq_path)
    if seq.height_mm is None:
        raise SequenceError(
            f"{seq.root}/sequence.json: rig.height_mm is missing (the camera height above the floor, mm)"
        )
    T_at, found = seq.groundtruth_at(seq.timestamps_s, max_diff_s=1e-3)
    T_frames: np.ndarray | None = None
    if found.any():
        T_frames = np.where(found[:, None, None], T_at, np.nan)  # NaN: a frame without a ground-truth pose
        if not found.all():
            log.warning("map: ground truth does not cover every frame; keyframe poses are chained (eq. 24)")
    return build_map_from_images(
        seq.image,
        seq.frame_count,
        seq.camera,
        seq.height_mm,
        timestamps_s=seq.timestamps_s,
        T_world_frames=T_frames,
        flatfield=seq.flatfield(),
        config=config,
        source=str(seq.root),
        on_progress=on_progress,
    )


# --------------------------------------------------------------------------- disk
@locks_folder("out_dir", "map folder")
def save_map(m: GlobalMap, out_dir: str | os.PathLike) -> Path:
    """Write ``out_dir/keyframes.npz`` then ``out_dir/map.json`` (both atomic), the folder locked
    (:func:`floorvo.locking.lock_folder`: a second writer of it is refused in one line)."""
    out = ensure_writable_dir(out_dir)
    offsets = np.concatenate([[0], np.cumsum([len(f) for f in m.features])]).astype(np.int64)
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        images=m.images.astype(np.uint8),
        kp_xy_px=np.concatenate([f.xy_px for f in m.features]).astype(np.float32),
        kp_desc=np.concatenate([f.desc for f in m.features]).astype(np.uint8),
        kp_offsets=offsets,
        vocab_words=m.vocab.words,
        vocab_idf=m.vocab.idf,
        T_world_kf=m.T_world_kf,
    )
    data = buf.getvalue()
    atomic_write_bytes(out / "keyframes.npz", data)
    meta = {
        "schema_version": MAP_SCHEMA_VERSION,
        "format": MAP_FORMAT,
        "units": {"translation": "mm", "angle": "rad"},
        "camera": m.camera.to_dict(),
        "height_mm": m.height_mm,
        "parameters": m.config.to_dict(),
        "source": m.source,
        "n_mapping_frames": m.n_mapping_frames,
        "n_keyframes": m.n_keyframes,
        "pose_source": m.pose_source,
        "chain_vs_groundtruth": m.chain_vs_groundtruth,
        "keyframes": [
            {"frame": int(f), "timestamp_s": float(t), "T_world_kf": T.tolist()}
            for f, t, T in zip(m.frame_indices, m.timestamps_s, m.T_world_kf)
        ],
        "arrays": {"file": "keyframes.npz", "sha256": hashlib.sha256(data).hexdigest()},
    }
    meta["content_sha256"] = json_sha256(meta)
    atomic_write_json(out / "map.json", meta)
    return out


#: The arrays of ``keyframes.npz``: dtype kind (``u`` unsigned, ``i`` signed, ``f`` float) and ndim.
MAP_ARRAYS = {
    "images": ("u", 3),
    "kp_xy_px": ("f", 2),
    "kp_desc": ("u", 2),
    "kp_offsets": ("iu", 1),
    "vocab_words": ("u", 2),
    "vocab_idf": ("f", 1),
    "T_world_kf": ("f", 3),
}


@dataclass(frozen=True)
class MapKeyframeEntry(Config):
    """One keyframe of ``map.json``."""

    frame: int = param(min=0, doc="frame index in the mapping sequence")
    timestamp_s: float = param(unit="s", doc="its time in the mapping sequence")
    T_world_kf: tuple[tuple[float, ...], ...] = param(doc="4x4 pose of the keyframe, mm")


@dataclass(frozen=True)
class MapArraysEntry(Config):
    """Where ``map.json`` finds its arrays, and their checksum."""

    file: str = param(doc="file name of the arrays, in the map folder")
    sha256: str = param(doc="SHA-256 of that file")


@dataclass(frozen=True)
class MapFile(Config):
    """The keys of ``map.json`` (read by :func:`load_map`, written by :func:`save_map`)."""

    schema_version: int = param(choices=MAP_SCHEMA_VERSIONS_READ, doc="map folder format version")
    format: str = param(choices=(MAP_FORMAT,), doc="format name")
    camera: dict = param(doc="intrinsics (CameraModel.to_dict)")
    height_mm: float = param(
        unit="mm", min=CAMERA_HEIGHT_RANGE_MM[0], max=CAMERA_HEIGHT_RANGE_MM[1], doc="camera height above the floor"
    )
    parameters: dict = param(doc="the MapConfig used")
    keyframes: tuple[dict, ...] = param(doc="frame, timestamp_s, T_world_kf of each keyframe")
    arrays: MapArraysEntry = param(doc="the arrays file and its checksum")
    content_sha256: str = param(doc="SHA-256 of this file's canonical JSON without this key")
    n_keyframes: int = param(min=1, doc="number of keyframes")
    n_mapping_frames: int = param(0, min=0, doc="frames of the mapping sequence")
    units: dict = param(default_factory=dict, doc="provenance: units")
    source: str = param("", doc="provenance: the mapping sequence")
    pose_source: str = param("chain", choices=POSE_SOURCES, doc="where the keyframe poses came from")
    chain_vs_groundtruth: dict = param(default_factory=dict, doc="the eq. (24) chain against ground truth")


def _pose(entry: MapKeyframeEntry, where: str) -> np.ndarray:
    T = np.array(entry.T_world_kf, dtype=float) if all(len(r) == 4 for r in entry.T_world_kf) else np.zeros(0)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise ConfigError(f"{where}.T_world_kf = {shown(entry.T_world_kf)}: must be a 4x4 matrix of finite numbers")
    return T


def _read_map_json(mj: Path) -> tuple[MapFile, CameraModel, MapConfig, list[MapKeyframeEntry], np.ndarray]:
    """``map.json`` checked in full: format, version, its own checksum, every key."""
    meta = read_json(mj, FloorbenchError)
    if not isinstance(meta, dict) or meta.get("format") != MAP_FORMAT:
        raise FloorbenchError(f"{mj}: not a floorbench map (format must be {MAP_FORMAT!r})")
    version = meta.get("schema_version")
    if type(version) is not int or version not in MAP_SCHEMA_VERSIONS_READ:
        raise FloorbenchError(f"{mj}: schema_version {shown(version)} is not {MAP_SCHEMA_VERSION} (rebuild the map)")
    written = meta.get("content_sha256")
    if written is None:
        raise FloorbenchError(f"{mj}: has no content_sha256 (written before maps were checksummed); rebuild the map")
    if written != json_sha256({k: v for k, v in meta.items() if k != "content_sha256"}):
        raise FloorbenchError(
            f"{mj}: content differs from its content_sha256 (edited or damaged); rebuild the map with `floorvo map`"
        )
    try:
        f = build(MapFile, meta)
        camera = CameraModel.from_dict(f.camera)
        cfg = MapConfig.from_dict(f.parameters)
        kfs = [build(MapKeyframeEntry, k, f"keyframes[{i}]") for i, k in enumerate(f.keyframes)]
        T = np.stack([_pose(k, f"keyframes[{i}]") for i, k in enumerate(kfs)]) if kfs else np.zeros((0, 4, 4))
    except ConfigError as exc:
        raise FloorbenchError(f"{mj}: {exc}") from None
    if version < 2 and camera.square_pinhole() != camera:
        raise FloorbenchError(
            f"{mj}: schema_version 1 map of a camera with distortion or fx != fy: its keyframes are in the "
            f"lens's own pixels, where fixes came out wrong; rebuild the map with `floorvo map`"
        )
    if f.n_keyframes != len(kfs):
        raise FloorbenchError(f"{mj}: n_keyframes = {f.n_keyframes}, but {len(kfs)} keyframes are listed")
    name = f.arrays.file
    if file_name_problem(name):
        raise FloorbenchError(f"{mj}: arrays.file = {shown(name)}: must be a file name in the map folder")
    return f, camera, cfg, kfs, T


def _read_map_arrays(npz: Path, sha256: str) -> dict[str, np.ndarray]:
    """The arrays of ``keyframes.npz``, whose bytes must have checksum ``sha256``."""
    if not npz.is_file():
        raise FloorbenchError(f"{npz}: keyframe arrays are missing")
    try:
        data = npz.read_bytes()
    except OSError as exc:
        raise FloorbenchError(f"{npz}: cannot be read ({exc.strerror or exc})") from None
    if hashlib.sha256(data).hexdigest() != sha256:
        raise FloorbenchError(
            f"{npz}: checksum differs from map.json (the files do not belong together, or one is damaged)"
        )

    def rule(kinds: str, ndim: int) -> Callable[[tuple[int, ...], np.dtype], str | None]:
        numbers = {"u": "unsigned integers", "f": "floats", "iu": "integers"}[kinds]
        return lambda shape, dtype: (
            None if dtype.kind in kinds and len(shape) == ndim else f"must be {ndim}-dimensional, of {numbers}"
        )

    # each header checked before its data is read: a crafted header could state terabytes
    return read_npz(data, {k: rule(*spec) for k, spec in MAP_ARRAYS.items()}, str(npz), error=FloorbenchError)


def _map_problem(arr: dict[str, np.ndarray], T: np.ndarray, camera: CameraModel, cfg: MapConfig) -> str | None:
    """The first way the arrays disagree with each other or with ``map.json``, or None."""
    K = len(T)
    images, off, xy, desc = arr["images"], arr["kp_offsets"], arr["kp_xy_px"], arr["kp_desc"]
    s = cfg.similarity.sim_scale
    size = (K, *downscale(np.zeros((camera.height_px, camera.width_px), np.uint8), s).shape)
    if images.dtype != np.uint8 or images.shape != size:
        return f"images {images.dtype} {images.shape}, expected uint8 {size} ({K} keyframes of the map's camera)"
    if len(off) != K + 1 or off[0] != 0 or np.any(np.diff(off) < 0) or off[-1] != len(xy) or len(xy) != len(desc):
        return "keypoint offsets do not match the keypoints"
    if xy.shape[1:] != (2,) or not np.isfinite(xy).all():
        return f"keypoints kp_xy_px {xy.shape}: must be (M, 2) finite pixels"
    words, idf = arr["vocab_words"], arr["vocab_idf"]
    if desc.dtype != np.uint8 or words.dtype != np.uint8 or len(words) == 0 or desc.shape[1] != words.shape[1]:
        return "descriptor width differs from the vocabulary's"
    if idf.shape != (len(words),) or not np.isfinite(idf).all():
        return f"vocab_idf {idf.shape}: must hold one finite weight per word ({len(words)})"
    if arr["T_world_kf"].shape != T.shape or not np.allclose(T, arr["T_world_kf"]):
        return "keyframe poses in map.json differ from keyframes.npz"
    return None


def load_map(path: str | os.PathLike) -> GlobalMap:
    """Read and validate a map folder written by :func:`save_map` (the one reader of the format).

    Every file is checked: ``map.json`` against its own ``content_sha256`` and key by key
    (:class:`MapFile`), ``keyframes.npz`` against the checksum ``map.json`` names, each array
    for its type and shape, and the arrays against ``map.json`` (poses, keyframe count, the
    camera's image size). Anything else is a one-line :class:`~floorvo.errors.FloorbenchError`.
    """
    root = Path(path)
    mj = root / "map.json"
    if not mj.is_file():
        raise FloorbenchError(
            f"{root}: not a map folder (map.json is missing); build one with `floorvo map SEQ -o MAP`"
        )
    f, camera, cfg, kfs, T = _read_map_json(mj)
    arr = _read_map_arrays(root / f.arrays.file, f.arrays.sha256)
    problem = _map_problem(arr, T, camera, cfg)
    if problem:
        raise FloorbenchError(f"{root}: inconsistent map: {problem}")
    off = arr["kp_offsets"]
    K = len(kfs)
    feats = [Features(arr["kp_xy_px"][off[k] : off[k + 1]], arr["kp_desc"][off[k] : off[k + 1]]) for k in range(K)]
    return GlobalMap(
        camera,
        f.height_mm,
        cfg,
        [k.frame for k in kfs],
        np.array([k.timestamp_s for k in kfs], float),
        T,
        arr["images"],
        feats,
        BinaryVocabulary(arr["vocab_words"], arr["vocab_idf"]),
        n_mapping_frames=f.n_mapping_frames,
        source=f.source,
        pose_source=f.pose_source,
        chain_vs_groundtruth=dict(f.chain_vs_groundtruth),
    )
