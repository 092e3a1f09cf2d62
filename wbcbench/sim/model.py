"""The MuJoCo model of a Robot, built with MjSpec from the same URDF or MJCF file pinocchio reads.

Collision geometry is limited to one box per sole matching the profile's rectangle (bottom face on the sole
plane) plus the terrain; every other body is collision-free. Sensors: a force and a torque sensor at each
ankle F/T frame of the profile, and an IMU (gyro, accelerometer, orientation) at the profile's IMU frame.

Self-collision checking (`SimOptions.self_collision`, default "off": the model above, unchanged): the URDF
collision meshes of the profile's `collision_check` links (MuJoCo collides their convex hulls), named
`selfcol:<link>:<k>`, in their own contype/conaffinity bits so that a side's effector (gripper) collides only
with the body links listed for that side, and with nothing else (floor, soles, each other):

    effector of side k (bit 4 left, 8 right): contype = bit_k, conaffinity = bits of the sides listing it as a body
    body link:                                contype = 0,     conaffinity = bits of the sides listing it

"physical": those geoms are part of the simulated model and their contacts act (default contact parameters), as
on the real robot. "detect": the simulated model stays exactly the "off" one (the motion is the one without the
geoms, a gripper may pass through the hips); `SelfCollisionMonitor` (self_collision.py) runs MuJoCo's collision
detection on a kinematic copy with the geoms (`build_self_collision_model`) at every tick and counts the
penetrations. MuJoCo's own "inactive contact" mechanism (margin/gap) was not used: with mesh geoms it generated
hundreds of far-away contacts per step and penetrations deeper than `gap` would have become active.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import mujoco
import numpy as np
import pinocchio as pin

from ..errors import ConfigError
from ..robots import Robot, Side
from ..types import GRAVITY, ActuationMode  # noqa: F401  (re-exported: the mode belongs to the shared vocabulary)
from ..scene import Terrain


@dataclass
class SimOptions:
    """Simulator settings. `timestep` [s] is the physics step; the control step is a multiple of it."""

    timestep: float = 1e-3
    integrator: str = "implicitfast"
    noslip_iterations: int = 0
    sole_friction: float = 1.0
    solref: tuple[float, float] = (0.02, 1.0)
    gravity: tuple[float, float, float] = (0.0, 0.0, -GRAVITY)
    self_collision: str = "off"
    visuals: bool = False
    extra: dict = field(default_factory=dict)
    realism: object = None  # a `wbcbench.sim.realism.Realism` (actuator chains, hip flexibility) or None: ideal

    def __post_init__(self) -> None:
        if self.self_collision not in SELF_COLLISION_MODES:
            raise ConfigError(f"unknown self_collision mode '{self.self_collision}'; allowed: "
                              f"{', '.join(SELF_COLLISION_MODES)}", key="self_collision")


#: SimOptions.self_collision values (see the module docstring).
SELF_COLLISION_MODES = ("off", "detect", "physical")
#: contype/conaffinity bit of each side's effector in the self-collision check.
SELF_COLLISION_BITS = {Side.LEFT: 4, Side.RIGHT: 8}


INTEGRATORS = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
               "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT, "rk4": mujoco.mjtIntegrator.mjINT_RK4}


def _urdf_for_mujoco(robot: Robot, keep_collision: frozenset[str] = frozenset()) -> str:
    """URDF text with visuals and collision meshes removed (except those of the links in `keep_collision`) and
    mesh packages and paths relative to the URDF resolved."""
    txt = robot.files.urdf.read_text()
    txt = re.sub(r"<visual\b.*?</visual>", "", txt, flags=re.S)
    if keep_collision:
        def link_block(m: re.Match) -> str:
            if m.group(2) in keep_collision:
                return m.group(0)
            return re.sub(r"<collision\b.*?</collision>", "", m.group(0), flags=re.S)

        txt = re.sub(r"(<link\b[^>]*?\bname=\"([^\"]+)\"[^>]*?(?<!/)>)(.*?)(</link>)", link_block, txt, flags=re.S)
        # collision elements left outside link blocks (none in URDFs we know) are removed as before
        parts = re.split(r"(<link\b.*?</link>)", txt, flags=re.S)
        txt = "".join(p if p.startswith("<link") else re.sub(r"<collision\b.*?</collision>", "", p, flags=re.S)
                      for p in parts)
    else:
        txt = re.sub(r"<collision\b.*?</collision>", "", txt, flags=re.S)
    txt = txt.replace("package://", str(robot.files.package_root) + "/")
    # mesh paths relative to the URDF (MjSpec.from_string has no directory to resolve them against)
    base = robot.files.urdf.parent
    txt = re.sub(r'(<mesh\b[^>]*?\bfilename=")(?![/\\]|[A-Za-z]:)([^"]+)"',
                 lambda m: f'{m.group(1)}{(base / m.group(2)).resolve()}"', txt)
    compiler = ('<mujoco><compiler discardvisual="true" fusestatic="true" strippath="false" '
                'balanceinertia="false" autolimits="true"/></mujoco>')
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + compiler, txt, count=1)


def _mjcf_for_mujoco(robot: Robot) -> mujoco.MjSpec:
    """The MjSpec of an MJCF robot, made like the URDF's: its free joint named "root"; its own actuators, sensors,
    keyframes, contact pairs and the world's geoms (a floor, scenery) removed (wbcbench adds its own). Its geoms
    are made collision-free after the self-collision check has picked its own (`_mjcf_collision_free`)."""
    file = str(robot.files.path)
    spec = mujoco.MjSpec.from_file(file)
    free = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        raise ConfigError(f"MJCF model '{file}' needs exactly one free joint (the floating base), found {len(free)}",
                          file=robot.profile.file or file, key="loader")
    if spec.equalities or spec.tendons:
        raise ConfigError(f"MJCF model '{file}' has equality constraints or tendons, which the pinocchio model "
                          "cannot follow; remove them", file=robot.profile.file or file, key="loader")
    free[0].name = "root"
    for group in (spec.actuators, spec.sensors, spec.keys, spec.pairs, spec.worldbody.geoms):
        for el in list(group):
            spec.delete(el)
    return spec


def _mjcf_collision_free(spec: mujoco.MjSpec) -> None:
    """Every geom of the MJCF but the self-collision check's collision-free (contype = conaffinity = 0): they keep
    their mass and are drawn, as the URDF's visuals; contacts are the soles' and the check's only."""
    for g in spec.geoms:
        if not g.name.startswith("selfcol:"):
            g.contype = g.conaffinity = 0


def _self_collision_bits(check: dict) -> tuple[dict, dict, dict]:
    """Of the `collision_check` bodies: their side (None for a body of both sides' checks, e.g. the torso), the
    contype bits of each side's effector links and the conaffinity bits of the bodies they are checked against."""
    owner: dict[str, Side | None] = {}
    contype: dict[str, int] = {}
    conaffinity: dict[str, int] = {}
    for side, c in check.items():
        for link in c.effector:
            owner[link] = side
            contype[link] = contype.get(link, 0) | SELF_COLLISION_BITS[side]
        for link in c.bodies:
            owner.setdefault(link, None)
            conaffinity[link] = conaffinity.get(link, 0) | SELF_COLLISION_BITS[side]
    return owner, contype, conaffinity


def _mjcf_self_collision_geoms(spec: mujoco.MjSpec, check: dict) -> None:
    """The MJCF's colliding geoms (contype or conaffinity set in the file) of the `collision_check` bodies in the
    self-collision bits (module docstring)."""
    owner, contype, conaffinity = _self_collision_bits(check)
    for link, side in owner.items():
        body = spec.body(link)
        geoms = [g for g in body.geoms if g.contype or g.conaffinity] if body is not None else []
        for k, g in enumerate(geoms):
            g.name = self_collision_geom_name(link, k)
            g.contype = contype.get(link, 0)
            g.conaffinity = conaffinity.get(link, 0)
            g.group = 3
            g.margin = 0.0
            g.gap = 0.0
            g.friction = [0.5, 0.005, 0.0001]


def _quat_wxyz(R: np.ndarray) -> np.ndarray:
    q = pin.Quaternion(R)
    return np.array([q.w, q.x, q.y, q.z])


def _rpy_quat(rpy) -> np.ndarray:
    return _quat_wxyz(pin.rpy.rpyToMatrix(*rpy))


def ft_site_name(side: Side) -> str:
    return f"ft_{side.value}"


def sole_geom_name(side: Side) -> str:
    return f"sole_{side.value}"


def self_collision_geom_name(link: str, k: int) -> str:
    """Name of the k-th collision geom of URDF link `link` in the self-collision check."""
    return f"selfcol:{link}:{k}"


def _collision_mesh_files(urdf: str) -> dict[str, list[tuple[str, list[float] | None] | None]]:
    """Per URDF link, its collision elements in order: (mesh file, scale or None), None for a primitive shape."""
    out: dict[str, list[tuple[str, list[float] | None] | None]] = {}
    for link in re.finditer(r"<link\b[^>]*?\bname=\"([^\"]+)\"[^>]*?(?<!/)>(.*?)</link>", urdf, flags=re.S):
        items = []
        for col in re.findall(r"<collision\b.*?</collision>", link.group(2), flags=re.S):
            mesh = re.search(r"<mesh\b[^>]*?\bfilename=\"([^\"]+)\"[^>]*?>", col)
            if mesh is None:
                items.append(None)
                continue
            scale = re.search(r"\bscale=\"([^\"]+)\"", mesh.group(0))
            items.append((mesh.group(1), [float(x) for x in scale.group(1).split()] if scale else None))
        out[link.group(1)] = items
    return out


def _own_meshes(spec: mujoco.MjSpec, link: str, geoms: list, files: list) -> None:
    """Give each mesh geom of `link` the mesh of its own URDF collision element. MuJoCo 3's URDF import names a
    mesh by its file's base name and gives a second file of the same base name the first one's mesh (TALOS:
    gripper/base_link_collision.STL got torso/base_link_collision.STL, the pelvis inside every gripper);
    MuJoCo 4 names them apart, and there nothing changes."""
    for k, (g, item) in enumerate(zip(geoms, files)):
        if item is None or g.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        path, scale = item
        current = spec.mesh(g.meshname)
        if current is not None and os.path.normpath(current.file) == os.path.normpath(path):
            continue
        mesh = spec.add_mesh(name=f"selfcol_mesh:{link}:{k}", file=path)
        if scale is not None:
            mesh.scale = scale
        g.meshname = mesh.name


def _self_collision_geoms(spec: mujoco.MjSpec, check: dict, urdf: str) -> None:
    """Name the kept URDF collision geoms (each with its own URDF mesh) and put them in the self-collision bits
    (module docstring)."""
    files = _collision_mesh_files(urdf)
    owner, contype, conaffinity = _self_collision_bits(check)
    for link in owner:
        body = spec.body(link)
        geoms = list(body.geoms) if body is not None else []
        side = owner[link]
        _own_meshes(spec, link, geoms, files.get(link, []))
        for k, g in enumerate(geoms):
            g.name = self_collision_geom_name(link, k)
            g.contype = contype.get(link, 0)
            g.conaffinity = conaffinity.get(link, 0)
            g.group = 3
            g.rgba = [0.9, 0.4, 0.1, 0.4] if side is not None else [0.4, 0.8, 0.4, 0.3]
            g.margin = 0.0
            g.gap = 0.0
            g.friction = [0.5, 0.005, 0.0001]


#: geom group of the URDF's visual meshes (rendering only)
VISUAL_GROUP = 2


def _visual_geoms(spec: mujoco.MjSpec, robot: Robot, body_of_joint: dict) -> None:
    """The URDF's visual meshes (pinocchio's visual geometry model) as visual-only geoms: no contact (contype and
    conaffinity 0), no mass (density 0), their own group (`VISUAL_GROUP`); so a run renders as the robot looks
    and simulates exactly as without them. Meshes MuJoCo cannot read (e.g. .dae) are left out."""
    spec.compiler.discardvisual = False  # (set for the URDF import, where it drops the URDF's own visuals)
    geom_model = pin.buildGeomFromUrdf(robot.model, str(robot.files.urdf), pin.GeometryType.VISUAL,
                                       package_dirs=[str(robot.files.package_root)])
    pmodel = robot.model
    for i, g in enumerate(geom_model.geometryObjects):
        path = str(g.meshPath or "")
        if not path.lower().endswith((".stl", ".obj")):
            continue
        mesh = spec.add_mesh(name=f"visual_mesh_{i}", file=path)
        mesh.scale = list(np.asarray(g.meshScale, dtype=float))
        body = body_of_joint[pmodel.names[g.parentJoint]] if g.parentJoint > 0 else spec.worldbody
        M = g.placement
        geom = body.add_geom(name=f"visual_{i}", type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh.name,
                             pos=M.translation, quat=_quat_wxyz(M.rotation))
        geom.contype = geom.conaffinity = 0
        geom.group = VISUAL_GROUP
        geom.density = 0.0
        geom.mass = 0.0
        color = np.asarray(g.meshColor, dtype=float)
        geom.rgba = list(color) if color.size == 4 and color[3] > 0 else [0.7, 0.7, 0.7, 1.0]


FLOOR_MATERIAL = "wbcbench_floor"
"""The floor's material in a model built with visuals (a checker of 0.5 m squares)."""


def _visual_scene(spec: mujoco.MjSpec) -> None:
    """What a picture needs and the dynamics never see (models built with visuals only): a sky that fades from blue
    at the zenith to white at the horizon, and a checker floor of 0.5 m squares, so that motion and depth read."""
    spec.add_texture(name="wbcbench_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.55, 0.72, 0.92], rgb2=[0.97, 0.98, 1.0],
                     width=64, height=384)
    spec.add_texture(name=FLOOR_MATERIAL, type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.86, 0.86, 0.84], rgb2=[0.74, 0.75, 0.74],
                     width=64, height=64)
    mat = spec.add_material(name=FLOOR_MATERIAL, texrepeat=[1.0, 1.0], texuniform=True, emission=0.35)
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = FLOOR_MATERIAL


def _realism_joints(spec: mujoco.MjSpec, robot: Robot, realism) -> None:
    """The preset's hidden mechanisms (wbcbench/sim/realism): motor-side friction on each actuated joint, a hidden
    `<joint>:drive` spring-damper in series (harmonic-drive elasticity) and `<joint>:hip_flex` (hip flexibility),
    each in the joint's body on its axis through its origin; the named joint stays the motor side (encoder)."""
    joints = {j.name: j for j in spec.joints}
    hinge = mujoco.mjtJoint.mjJNT_HINGE

    def series(j, suffix: str, stiffness: float, damping: float) -> None:
        h = j.parent.add_joint(name=f"{j.name}:{suffix}", type=hinge, pos=list(j.pos), axis=list(j.axis))
        h.stiffness = [stiffness, 0.0, 0.0]  # (MuJoCo 4: linear coefficient first)
        h.damping = [damping, 0.0, 0.0]
        h.armature = 0.0

    for i, name in enumerate(robot.joint_names):
        j = joints[name]
        if j.type != hinge:
            raise ConfigError(f"joint '{name}' is not a hinge; the actuator model handles hinges only",
                              file=realism.file, key="actuators")
        # the joint's whole break-away torque; with the default friction model the simulator moves it from MuJoCo's
        # constraint into its stick-slip kernel (`Simulator`, wbcbench/sim/friction_kernel.py)
        j.frictionloss = j.frictionloss + realism.coulomb[i]
        d = realism.stiction_impedance
        if realism.coulomb[i] > 0 and d is not None:  # the constraint made near-hard: MuJoCo's default soft
            j.solref_friction = [2.0 * spec.option.timestep, 1.0]  # friction lets a joint creep below break-away
            j.solimp_friction = [d, 1.0 - (1.0 - d) / 10.0, 0.001, 0.5, 2.0]  # (mrad/s); as stiff as is stable
        damping = np.array(j.damping, dtype=float).reshape(-1)
        damping[0] += realism.viscous[i]
        j.damping = damping
        if realism.stiffness[i] > 0:
            series(j, "drive", realism.stiffness[i], realism.damping[i])
    if realism.hip is not None:
        # in the parent link (the structure above the hip joint), on the hip joint's axis through its origin
        # expressed there: a separate body from the drive's, so the two compliances stay distinct degrees of freedom
        # (two massless hinges on one axis in one body would make the inertia matrix singular)
        for name in realism.hip.joints:
            j = joints[name]
            body = j.parent
            if body.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:  # (an MJCF body turned by euler...)
                raise ConfigError(f"hip flexibility needs the body of '{name}' oriented by a quaternion in the model",
                                  file=realism.file, key="hip")
            R = pin.Quaternion(*np.asarray(body.quat, dtype=float)).toRotationMatrix()  # (w, x, y, z)
            h = body.parent.add_joint(name=f"{name}:hip_flex", type=hinge,
                                      pos=list(np.asarray(body.pos, dtype=float) + R @ np.asarray(j.pos, dtype=float)),
                                      axis=list(R @ np.asarray(j.axis, dtype=float)))
            h.stiffness = [realism.hip.stiffness, 0.0, 0.0]
            h.damping = [realism.hip.damping, 0.0, 0.0]


def build_mujoco_model(robot: Robot, terrain: Terrain, mode: ActuationMode,
                       options: SimOptions | None = None) -> mujoco.MjModel:
    """Compile the MuJoCo model of `robot` standing in `terrain`, with actuators for `mode`."""
    options = options or SimOptions()
    check = robot.profile.collision_check if options.self_collision == "physical" else {}
    if options.self_collision != "off" and set(robot.profile.collision_check) != set(Side):
        raise ConfigError("self-collision checking needs a `collision_check` section for both sides",
                          file=robot.profile.file, key="collision_check")
    keep = frozenset(link for c in check.values() for link in (*c.effector, *c.bodies))
    mjcf = robot.files.is_mjcf
    if mjcf:
        spec = _mjcf_for_mujoco(robot)
        base = spec.joint("root").parent
    else:
        urdf = _urdf_for_mujoco(robot, keep)
        spec = mujoco.MjSpec.from_string(urdf)
        base = spec.worldbody.first_body()
        base.add_freejoint(name="root")
    pmodel = robot.model
    spec.option.timestep = options.timestep
    spec.option.integrator = INTEGRATORS[options.integrator]
    spec.option.noslip_iterations = options.noslip_iterations
    spec.option.gravity = list(options.gravity)
    if robot.profile.min_body_mass > 0:
        spec.compiler.boundmass = robot.profile.min_body_mass
    if robot.profile.min_body_inertia > 0:
        spec.compiler.boundinertia = robot.profile.min_body_inertia

    # the body owning each pinocchio joint (MuJoCo body frame == URDF child link frame == pinocchio joint frame)
    body_of_joint = {}
    for j in spec.joints:
        if j.name != "root":
            body_of_joint[j.name] = j.parent
    body_of_joint[pmodel.names[1]] = base

    def body_and_placement(frame_name: str) -> tuple[mujoco.MjsBody, pin.SE3]:
        f = pmodel.frames[pmodel.getFrameId(frame_name)]
        body = body_of_joint[pmodel.names[f.parentJoint]]
        if not mjcf:
            return body, f.placement
        # MJCF: a joint may sit away from its body's origin (<joint pos>); pinocchio's body frame says where the
        # body is in the joint frame, and the placement is taken from there
        b = pmodel.frames[pmodel.getFrameId(body.name, pin.FrameType.BODY)]
        return body, b.placement.actInv(f.placement)

    # joints: armature from pinocchio (rotor inertia x gear ratio^2), absent in the URDF
    for j in spec.joints:
        if j.name == "root":
            continue
        jid = pmodel.getJointId(j.name)
        j.armature = float(pmodel.armature[pmodel.idx_vs[jid]])
    if options.realism is not None:
        _realism_joints(spec, robot, options.realism)

    if check:
        if mjcf:
            _mjcf_self_collision_geoms(spec, check)
        else:
            _self_collision_geoms(spec, check, urdf)
    if mjcf:
        _mjcf_collision_free(spec)
    if options.visuals:
        if not mjcf:  # (an MJCF's own geoms are its visuals, kept)
            _visual_geoms(spec, robot, body_of_joint)
        _visual_scene(spec)

    # sole boxes and F/T sites
    sole = robot.profile.sole
    for side in Side:
        body, M = body_and_placement(robot.profile.feet[side].frame)
        center = M.act(np.array([sole.center[0], sole.center[1], sole.thickness / 2]))
        g = body.add_geom(name=sole_geom_name(side), type=mujoco.mjtGeom.mjGEOM_BOX,
                          size=[sole.length / 2, sole.width / 2, sole.thickness / 2],
                          pos=center, quat=_quat_wxyz(M.rotation))
        g.friction = [options.sole_friction, 0.005, 0.0001]
        g.solref = list(options.solref)
        g.contype, g.conaffinity = 1, 1
        g.rgba = [0.2, 0.2, 0.8, 1]
        body, M = body_and_placement(robot.profile.feet[side].ft_sensor_frame)
        body.add_site(name=ft_site_name(side), pos=M.translation, quat=_quat_wxyz(M.rotation))
        for kind, t in (("force", mujoco.mjtSensor.mjSENS_FORCE), ("torque", mujoco.mjtSensor.mjSENS_TORQUE)):
            spec.add_sensor(name=f"{kind}_{side.value}", type=t, objtype=mujoco.mjtObj.mjOBJ_SITE,
                            objname=ft_site_name(side))
    body, M = body_and_placement(robot.profile.imu_frame)
    body.add_site(name="imu", pos=M.translation, quat=_quat_wxyz(M.rotation))
    for name, t in (("gyro", mujoco.mjtSensor.mjSENS_GYRO), ("accelerometer", mujoco.mjtSensor.mjSENS_ACCELEROMETER),
                    ("imu_quat", mujoco.mjtSensor.mjSENS_FRAMEQUAT)):
        spec.add_sensor(name=name, type=t, objtype=mujoco.mjtObj.mjOBJ_SITE, objname="imu")

    # terrain
    if terrain.floor:
        floor = spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
        floor.friction = [terrain.friction, 0.005, 0.0001]
        floor.rgba = [0.5, 0.5, 0.5, 1]
        if options.visuals:
            floor.material = FLOOR_MATERIAL
    for i, b in enumerate(terrain.boxes):
        g = spec.worldbody.add_geom(name=b.name or f"terrain_{i}", type=mujoco.mjtGeom.mjGEOM_BOX,
                                    size=[s / 2 for s in b.size], pos=list(b.center), quat=_rpy_quat(b.rpy))
        g.friction = [terrain.friction, 0.005, 0.0001]
        g.rgba = [0.6, 0.5, 0.4, 1]

    # actuators, one per actuated joint, in pinocchio order
    kp, kd = robot.profile.position_gains.resolve(robot.joint_names, robot.profile.file)
    effort = robot.effort_limit
    if options.realism is not None:  # the current limit, where the preset has one below the URDF's
        effort = np.minimum(effort, np.asarray(options.realism.torque_limit, dtype=float))
    for i, jname in enumerate(robot.joint_names):
        a = spec.add_actuator(name=jname, target=jname, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.forcelimited = True
        a.forcerange = [-effort[i], effort[i]]
        if mode is ActuationMode.POSITION:
            a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            a.gainprm[0] = kp[i]
            a.biasprm[0:3] = [0.0, -kp[i], -kd[i]]
        else:
            a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            a.biastype = mujoco.mjtBias.mjBIAS_NONE
            a.gainprm[0] = 1.0
            a.ctrllimited = True
            a.ctrlrange = [-effort[i], effort[i]]
    model = spec.compile()
    if mjcf:
        _check_masses(robot, model)
    return model


def _check_masses(robot: Robot, model: mujoco.MjModel) -> None:
    """An MJCF body without <inertial> gets its mass from its geoms in MuJoCo and none in pinocchio: refused, as
    the two models would disagree."""
    mj_mass = float(np.sum(model.body_mass))
    if abs(mj_mass - robot.mass) > 1e-9 * max(1.0, robot.mass):
        raise ConfigError(f"MJCF model '{robot.files.path}': MuJoCo's mass {mj_mass:.6f} kg differs from pinocchio's "
                          f"{robot.mass:.6f} kg (bodies whose inertia MuJoCo infers from geoms); give every body an "
                          "<inertial>", file=robot.profile.file or str(robot.files.path), key="loader")


def build_self_collision_model(robot: Robot) -> mujoco.MjModel:
    """The kinematic copy used by "detect" self-collision checking: the robot with its `collision_check` geoms
    (no floor, torque actuators); only its kinematics and collision detection are ever run."""
    return build_mujoco_model(robot, Terrain(floor=False), ActuationMode.TORQUE, SimOptions(self_collision="physical"))
