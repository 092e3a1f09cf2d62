"""Convert a CMU ASF/AMC pair to BVH, keeping the ASF names and length unit (how the `cmu_asf_*` clips of this corpus
were made, see MANIFEST.yaml; then trimmed with trim.py):

    python tests/data/teleop/asf2bvh.py SUBJECT.asf TRIAL.amc OUT.bvh [--rate 120]

Each BVH joint is the start of its ASF bone: its offset is the parent bone's direction times its length (zero under
the root), its rest orientation the identity, and its rotation the ASF one expressed in the rest (world) axes,
``L = C Rz(rz) Ry(ry) Rx(rx) C^-1`` with ``C`` the bone's ``axis`` (x, then y, then z about the fixed axes), written
as Z, Y, X channels; a bone with no child ends in an end site along its own direction.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.spatial.transform import Rotation

from wbcbench.teleop.io.bvh import BvhJoint, BvhSkeleton, write_bvh

_ROT = ("Zrotation", "Yrotation", "Xrotation")


def parse_asf(path: str) -> tuple[dict, dict, list]:
    """(root {order, axis}, bones {name: {direction, length, axis, dof}}, hierarchy [(parent, child)] in file order)."""
    section, bones, edges, root, bone = None, {}, [], {"axis": np.zeros(3)}, None
    for raw in open(path, encoding="latin-1"):  # comments may hold non-UTF-8 text (HDM05 paths)
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            section = line.split()[0][1:]
            continue
        words = line.split()
        if section == "root" and words[0] == "orientation":
            root["axis"] = np.array([float(w) for w in words[1:4]])
        elif section == "bonedata":
            if words[0] == "begin":
                bone = {"dof": [], "axis": np.zeros(3)}
            elif words[0] == "end":
                bones[bone["name"]] = bone
            elif words[0] == "name":
                bone["name"] = words[1]
            elif words[0] == "direction":
                bone["direction"] = np.array([float(w) for w in words[1:4]])
            elif words[0] == "length":
                bone["length"] = float(words[1])
            elif words[0] == "axis":
                if words[4].upper() != "XYZ":
                    raise SystemExit(f"{path}: axis order {words[4]} of {bone['name']} is not handled")
                bone["axis"] = np.array([float(w) for w in words[1:4]])
            elif words[0] == "dof":
                bone["dof"] = [w.lower() for w in words[1:]]
        elif section == "hierarchy" and words[0] not in ("begin", "end"):
            edges += [(words[0], child) for child in words[1:]]
    return root, bones, edges


def parse_amc(path: str) -> list[dict]:
    """Frames: {bone: [values in dof order]}."""
    frames: list[dict] = []
    for raw in open(path, encoding="latin-1"):  # comments may hold non-UTF-8 text (HDM05 paths)
        line = raw.strip()
        if not line or line.startswith(("#", ":")):
            continue
        words = line.split()
        if len(words) == 1 and words[0].isdigit():
            frames.append({})
        else:
            frames[-1][words[0]] = [float(w) for w in words[1:]]
    return frames


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("asf")
    ap.add_argument("amc")
    ap.add_argument("out")
    ap.add_argument("--rate", type=float, default=120.0, help="[Hz] the AMC's frame rate (CMU: 120)")
    a = ap.parse_args(argv)
    root, bones, edges = parse_asf(a.asf)
    children: dict[str, list[str]] = {}
    for parent, child in edges:
        children.setdefault(parent, []).append(child)
    order, joints = [], []

    def add(name: str, parent: int) -> None:
        index = len(joints)
        if name == "root":
            offset, channels = (0.0, 0.0, 0.0), ("Xposition", "Yposition", "Zposition") + _ROT
        else:
            up = bones.get(joints[parent].name)
            offset = tuple(up["direction"] * up["length"]) if up is not None else (0.0, 0.0, 0.0)
            channels = _ROT
        end = None
        if name != "root" and not children.get(name):
            end = tuple(bones[name]["direction"] * bones[name]["length"])
        joints.append(BvhJoint(name=name, parent=parent, offset=offset, channels=channels, end_site=end))
        order.append(name)
        for child in children.get(name, []):
            add(child, index)

    add("root", -1)
    axes = {name: Rotation.from_euler("xyz", b["axis"], degrees=True) for name, b in bones.items()}
    axes["root"] = Rotation.from_euler("xyz", root["axis"], degrees=True)
    rows = []
    for frame in parse_amc(a.amc):
        row = []
        for name in order:
            values = frame.get(name, [])
            if name == "root":
                row += values[:3]
                angles = dict(zip(("rx", "ry", "rz"), values[3:6]))
            else:
                angles = dict(zip(bones[name]["dof"], values))
            r = Rotation.from_euler("xyz", [angles.get(k, 0.0) for k in ("rx", "ry", "rz")], degrees=True)
            local = axes[name] * r * axes[name].inv()
            row += list(local.as_euler("ZYX", degrees=True))
        rows.append(row)
    write_bvh(a.out, BvhSkeleton(tuple(joints)), np.asarray(rows), 1.0 / a.rate, decimals=4)
    print(f"{a.out}: {len(rows)} frames, {len(joints)} joints")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
