"""Keyframe map and relocalisation after kidnapping (paper 003) on the paper003 scenes.

Builds the map from ``scenes/paper003_map.toml`` (lawnmower), localises every frame of
``scenes/paper003_kidnap.toml`` (teleports) against it with no use of earlier poses, and
reports: keyframe fraction of the mapping frames (paper 003: < 5 %), the eq. (24) chain's
error against the ground truth (the map takes the ground-truth poses unless --poses chain),
localisation RMSE, success rate, frames to recover after each kidnap (0 = the first frame
after landing), time per query on one core, and the retrieval time for a map of thousands
of keyframes.

Frames come from the scenes' trajectories over a procedural floor texture by exact warps
(default: no renderer, seconds), or, with ``--rendered``, from Mitsuba renders of the two
scenes (``--scale`` shrinks them; slow on 2 cores)::

    .venv/bin/python benchmarks/relocalisation.py -o out/reloc
    .venv/bin/python benchmarks/relocalisation.py --rendered --scale 0.5 -o out/reloc_rendered
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from floorvo.geometry import se2_from_T  # noqa: E402
from floorvo.mapping.localize import Localizer  # noqa: E402
from floorvo.mapping.map import MapConfig, build_map_from_images  # noqa: E402
from floorvo.mapping.retrieval import KeyframeIndex, VoteIndex  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def se2_err(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    d = se2_from_T(T_est) - se2_from_T(T_true)
    return float(np.hypot(d[0], d[1])), float(abs((d[2] + np.pi) % (2 * np.pi) - np.pi))


def synthetic_sources(map_scene, kid_scene, texture_seed: int, noise_std: float):
    from floorvo import synthetic as syn

    cam = map_scene.camera_model()
    h = map_scene.camera.height_mm
    g = cam.gsd_mm_per_px(h)
    Tm = map_scene.build_trajectory().T_world_cam
    tk = kid_scene.build_trajectory()
    xs = np.concatenate([Tm[:, 0, 3], tk.T_world_cam[:, 0, 3]])
    ys = np.concatenate([Tm[:, 1, 3], tk.T_world_cam[:, 1, 3]])
    centre = (0.5 * (xs.min() + xs.max()), 0.5 * (ys.min() + ys.max()))
    half = max(xs.max() - xs.min(), ys.max() - ys.min()) / 2 + np.hypot(cam.width_px, cam.height_px) * g / 2 + 5
    size = int(2 * half / g) + 8
    t0 = time.perf_counter()
    tex = syn.floor_texture(size, seed=texture_seed)
    print(f"texture {size} x {size} px ({size * g:.0f} mm square) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    rng_m, rng_k = np.random.default_rng(1), np.random.default_rng(2)

    def map_img(i):
        return syn.view(tex, cam, Tm[i], h, noise_std=noise_std, rng=rng_m, centre_mm=centre)

    def kid_img(i):
        return syn.view(tex, cam, tk.T_world_cam[i], h, noise_std=noise_std, rng=rng_k, centre_mm=centre)

    return cam, h, Tm, map_img, None, tk.T_world_cam, tk.events.get("teleport_frames", []), kid_img, None, size


def rendered_sources(map_scene, kid_scene, out: Path, scale: float | None, spp: int | None):
    from floorsim.simulate import render_sequence
    from floorvo.sequence import Sequence

    seqs = []
    for sc in (map_scene, kid_scene):
        t0 = time.perf_counter()
        import hashlib

        tag = hashlib.sha256(json.dumps(sc.to_dict(), sort_keys=True, default=str).encode()).hexdigest()[:8]
        p = render_sequence(sc, out / "sequences" / f"{sc.name}-{tag}", scale=scale, spp=spp)
        print(f"rendered {sc.name} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
        seqs.append(Sequence.open(p))
    sm, sk = seqs
    Tm = sm.groundtruth()[1]
    Tk = sk.groundtruth()[1]
    tele = sk.meta.get("events", {}).get("teleport_frames") if hasattr(sk, "meta") else None
    if tele is None:
        tele = kid_scene.build_trajectory().events.get("teleport_frames", [])
    return sm.camera, sm.height_mm, Tm, sm.image, sm.flatfield(), Tk, tele, sk.image, sk.flatfield(), None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "out" / "relocalisation")
    ap.add_argument("--map-scene", default=str(ROOT / "scenes" / "paper003_map.toml"))
    ap.add_argument("--kidnap-scene", default=str(ROOT / "scenes" / "paper003_kidnap.toml"))
    ap.add_argument(
        "--rendered", action="store_true", help="render the scenes with Mitsuba instead of warping a texture"
    )
    ap.add_argument("--scale", type=float, default=None, help="render scale (rendered mode)")
    ap.add_argument("--spp", type=int, default=None, help="samples per pixel (rendered mode)")
    ap.add_argument("--texture-seed", type=int, default=3)
    ap.add_argument("--noise", type=float, default=2.0, help="sensor noise std in grey levels (synthetic mode)")
    ap.add_argument("--map-set", action="append", metavar="KEY=VALUE", help="override a key of the map scene")
    ap.add_argument("--kidnap-set", action="append", metavar="KEY=VALUE", help="override a key of the kidnap scene")
    ap.add_argument(
        "--vote-bits", type=int, default=None, help="Hamming radius of the descriptor votes (default: VoteIndex's 48)"
    )
    ap.add_argument("--big-map", type=int, default=5000, help="keyframes of the large map for the retrieval timing")
    ap.add_argument(
        "--poses",
        choices=("groundtruth", "chain"),
        default="groundtruth",
        help="keyframe poses: the mapping run's ground truth (as `floorvo map` does by default) or the eq. (24) chain",
    )
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    from floorsim.scene import load_scene
    from floorvo.cli.common import parse_set_args

    map_scene = load_scene(args.map_scene, parse_set_args(args.map_set))
    kid_scene = load_scene(args.kidnap_scene, parse_set_args(args.kidnap_set))
    args.out.mkdir(parents=True, exist_ok=True)
    if args.rendered:
        cam, h, Tm, map_img, flat_m, Tk, tele, kid_img, flat_k, tex_px = rendered_sources(
            map_scene, kid_scene, args.out, args.scale, args.spp
        )
    else:
        cam, h, Tm, map_img, flat_m, Tk, tele, kid_img, flat_k, tex_px = synthetic_sources(
            map_scene, kid_scene, args.texture_seed, args.noise
        )

    t0 = time.perf_counter()
    gmap = build_map_from_images(
        map_img, len(Tm), cam, h, T_world_frames=Tm, flatfield=flat_m, config=MapConfig(poses=args.poses)
    )
    t_map = time.perf_counter() - t0
    chain = gmap.chain_vs_groundtruth  # eq. (24) chained keyframe poses against the ground truth
    if args.vote_bits is not None:
        gmap._vote_index = VoteIndex(
            [f.desc for f in gmap.features], max_hamming_bits=args.vote_bits, seed=gmap.config.seed
        )

    loc = Localizer(gmap, flatfield=flat_k)
    loc.localize(kid_img(0))  # warm-up (allocations, ORB object)
    ok, errs, ms, reasons, stages = [], [], [], [], []
    for i in range(len(Tk)):
        img = kid_img(i)
        r = loc.localize(img)
        ms.append(r.timing_ms["total"])
        stages.append([r.timing_ms[k] for k in ("detect", "match", "estimate")])
        ok.append(r.ok)
        errs.append(se2_err(r.T_world_cam, Tk[i]) if r.ok else (np.nan, np.nan))
        if not r.ok:
            reasons.append({"frame": i, "reason": r.reason})
    ok = np.array(ok)
    d = np.array([e[0] for e in errs])
    a = np.array([e[1] for e in errs])
    good = ok & (d < 1.0)
    recover = []
    for f in tele:
        k = next((j - f for j in range(f, len(Tk)) if good[j]), None)
        recover.append(k)

    # Retrieval for a map of thousands of keyframes: the inverted index over `big_map`
    # keyframes (the real keyframes plus perturbed copies), queried with real frames.
    # Descriptor voting (the default) and the bag of words, each timed on both maps.
    # The extra keyframes are the real ones' descriptors with 30 % of their bits flipped
    # (distinct, ORB-like, never true matches); exact copies would pile into LSH buckets.
    rng = np.random.default_rng(5)
    reps = [f.desc for f in gmap.features]
    while len(reps) < args.big_map:
        base = gmap.features[len(reps) % gmap.n_keyframes].desc
        flips = np.packbits(rng.random((len(base), 256)) < 0.3, axis=1)
        reps.append(np.bitwise_xor(base, flips))
    t_b = time.perf_counter()
    big_vote = VoteIndex(reps)
    t_big_build = time.perf_counter() - t_b
    big_bow = KeyframeIndex(gmap.vocab, reps)
    from floorvo.mapping.similarity import detect_features, prepare_image

    q = [
        detect_features(prepare_image(kid_img(i), flat_k), gmap.config.similarity).desc
        for i in range(0, len(Tk), max(1, len(Tk) // 10))
    ]
    ret = {}
    for name, idx in (
        ("vote_map", gmap.vote_index),
        ("vote_big", big_vote),
        ("bow_map", gmap.index),
        ("bow_big", big_bow),
    ):
        idx.query(q[0], 3)
        t1 = time.perf_counter()
        for x in q:
            idx.query(x, 3)
        ret[name] = (time.perf_counter() - t1) / len(q) * 1e3
    t_small, t_big = ret["vote_map"], ret["vote_big"]

    summary = {
        "mode": "rendered" if args.rendered else "synthetic texture warps",
        "scale": args.scale,
        "map_overrides": args.map_set or [],
        "kidnap_overrides": args.kidnap_set or [],
        "camera": f"{cam.width_px}x{cam.height_px}",
        "gsd_mm_per_px": cam.gsd_mm_per_px(h),
        "texture_px": tex_px,
        "map_frames": int(len(Tm)),
        "keyframes": gmap.n_keyframes,
        "keyframe_fraction_pct": 100.0 * gmap.keyframe_fraction,
        "map_build_s": t_map,
        "keyframe_poses": args.poses,
        "chain_vs_groundtruth_rms_mm": chain["rms_mm"],
        "chain_vs_groundtruth_max_mm": chain["max_mm"],
        "kidnap_frames": int(len(Tk)),
        "teleport_frames": list(map(int, tele)),
        "success_rate_pct": 100.0 * float(ok.mean()),
        "within_1mm_pct": 100.0 * float(good.mean()),
        "loc_rmse_mm": float(np.sqrt(np.nanmean(d[ok] ** 2))) if ok.any() else float("nan"),
        "loc_max_mm": float(np.nanmax(d[ok])) if ok.any() else float("nan"),
        "loc_yaw_rmse_deg": float(np.degrees(np.sqrt(np.nanmean(a[ok] ** 2)))) if ok.any() else float("nan"),
        "frames_to_recover": recover,
        "query_ms_median": float(np.median(ms)),
        "query_ms_p95": float(np.percentile(ms, 95)),
        "query_ms_median_stages": dict(
            zip(("detect", "retrieve_and_fit", "similarity"), np.median(stages, axis=0).round(2).tolist())
        ),
        "retrieval_ms_map": t_small,
        f"retrieval_ms_{args.big_map}_keyframes": t_big,
        "retrieval_ms_all": ret,
        f"vote_index_build_s_{args.big_map}_keyframes": t_big_build,
        "not_localised": reasons,
        "threads": "cv2.setNumThreads(1), OMP_NUM_THREADS=1",
    }
    (args.out / "relocalisation.json").write_text(json.dumps(summary, indent=2) + "\n")
    rows = [
        (
            "keyframes / mapping frames",
            f"{gmap.n_keyframes} / {len(Tm)} = {summary['keyframe_fraction_pct']:.1f} % (paper: < 5 %)",
        ),
        ("keyframe poses used", args.poses),
        ("eq. (24) chain against ground truth", f"RMS {chain['rms_mm']:.3f} mm, max {chain['max_mm']:.3f} mm"),
        (
            "localised (kidnap run)",
            f"{summary['success_rate_pct']:.1f} % of {len(Tk)} frames; within 1 mm {summary['within_1mm_pct']:.1f} %",
        ),
        (
            "localisation error",
            f"RMSE {summary['loc_rmse_mm']:.3f} mm (max {summary['loc_max_mm']:.3f}), yaw RMSE {summary['loc_yaw_rmse_deg']:.4f} deg",
        ),
        (
            "frames to recover after each kidnap",
            ", ".join(str(x) for x in recover) + " (0 = first frame after landing)",
        ),
        (
            "time per query, one core",
            f"median {summary['query_ms_median']:.1f} ms, p95 {summary['query_ms_p95']:.1f} ms; stages (median ms) {summary['query_ms_median_stages']}",
        ),
        (
            "retrieval only (descriptor voting, LSH)",
            f"{t_small:.2f} ms ({gmap.n_keyframes} keyframes), {t_big:.2f} ms ({args.big_map} keyframes; index built in {t_big_build:.1f} s)",
        ),
        (
            "retrieval only (bag of words)",
            f"{ret['bow_map']:.2f} ms ({gmap.n_keyframes} keyframes), {ret['bow_big']:.2f} ms ({args.big_map} keyframes)",
        ),
        ("map build", f"{t_map:.1f} s"),
    ]
    print("| quantity | value |\n|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
