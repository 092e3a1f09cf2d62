"""Add a static trial's knee and ankle markers to a motion trial that lacks them, through the thigh and shank marker
clusters (how the `opensim_walk` clip of this corpus was made, see MANIFEST.yaml; then trimmed with trim.py):

    python tests/data/teleop/cast_markers.py STATIC.trc MOTION.trc [MORE.trc ...] OUT.trc

(several motion files: consecutive pieces of one trial, joined in the order given.)

OpenSim's gait marker set puts the knee (``R.Knee.Lat``/``.Med``) and ankle (``R.Ankle.Lat``/``.Med``) markers on
the static trial only; the motion trials carry three-marker clusters on each thigh and shank (``R.Thigh.Upper``
``.Front`` ``.Rear``, ``R.Shank.Upper`` ``.Front`` ``.Rear``). Calibrated anatomical systems technique (Cappozzo et
al., Clin. Biomech. 10:171, 1995): each anatomical marker is expressed in its cluster's mean static
configuration, and placed in every motion frame by the rigid transform (least squares, Kabsch) that takes the
static cluster onto the frame's cluster; the knee markers ride on the thigh cluster, the ankle markers on the shank
cluster. The clusters' fit residuals are printed (skin motion and marker noise).
"""

from __future__ import annotations

import argparse

import numpy as np

from wbcbench.teleop.io.trc import read_trc_markers, write_trc

#: cluster -> the anatomical markers it carries (labels without the side prefix)
CLUSTERS = {("Thigh.Upper", "Thigh.Front", "Thigh.Rear"): ("Knee.Lat", "Knee.Med"),
            ("Shank.Upper", "Shank.Front", "Shank.Rear"): ("Ankle.Lat", "Ankle.Med")}


def rigid_fit(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R (N, 3, 3), t (N, 3)) minimising |R A + t - B(n)| for one point set `A` (P, 3) and frames `B` (N, P, 3)."""
    a0 = A.mean(axis=0)
    b0 = B.mean(axis=1)
    H = np.einsum("pi,npj->nij", A - a0, B - b0[:, None])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("nij,njk->nik", U, Vt)))
    D = np.tile(np.eye(3), (len(B), 1, 1))
    D[:, 2, 2] = d
    R = np.einsum("nji,njk,nlk->nil", Vt, D, U)  # V D U^T
    return R, b0 - np.einsum("nij,j->ni", R, a0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("static")
    ap.add_argument("motion", nargs="+")
    ap.add_argument("out")
    a = ap.parse_args(argv)
    s_labels, s_xyz, _ = read_trc_markers(a.static)
    pieces = [read_trc_markers(f) for f in a.motion]
    labels, _, rate = pieces[0]
    for f, (other, _, r) in zip(a.motion, pieces):
        if other != labels or r != rate:
            raise SystemExit(f"{f}: its markers or rate differ from {a.motion[0]}'s")
    xyz = np.concatenate([x for _, x, _ in pieces])
    static = {k: s_xyz[:, i] for i, k in enumerate(s_labels)}
    markers = {k: xyz[:, i] for i, k in enumerate(labels)}
    for side in ("R", "L"):
        for cluster, carried in CLUSTERS.items():
            names = [f"{side}.{c}" for c in cluster]
            A = np.stack([np.nanmean(static[n], axis=0) for n in names])  # (3, 3) mean static cluster [m]
            B = np.stack([markers[n] for n in names], axis=1)  # (N, 3, 3)
            R, t = rigid_fit(A, B)
            fit = np.einsum("nij,pj->npi", R, A) + t[:, None]
            rms = np.sqrt(np.nanmean(np.sum((fit - B) ** 2, axis=-1)))
            for c in carried:
                local = np.nanmean(static[f"{side}.{c}"], axis=0)
                markers[f"{side}.{c}"] = np.einsum("nij,j->ni", R, local) + t
            print(f"{side}.{cluster[0].split('.')[0]}: cluster fit residual {1000 * rms:.1f} mm (RMS), "
                  f"added {', '.join(f'{side}.{c}' for c in carried)}")
    write_trc(a.out, markers, rate, units="mm")
    print(f"{a.out}: {len(xyz)} frames of {len(markers)} markers at {rate:g} Hz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
