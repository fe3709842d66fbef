"""MJCF (MuJoCo XML) loader: the compiled ``mujoco.MjModel`` becomes a :class:`RobotModel`.

MuJoCo compiles the file first (includes, defaults, ``fromto``, Euler angles, degrees, mesh
re-centring), and the loader reads the compiled arrays, so every MJCF feature MuJoCo knows is
honoured. Conventions of the result:

* **Links.** Each body becomes a link of the same name (an unnamed body is ``body<id>``); the
  world body is the root link ``world``. A body without joints hangs from its parent on a fixed
  joint ``<body>__weld``.
* **Joints.** ``hinge`` -> revolute (``continuous`` when not limited), ``slide`` -> prismatic,
  limits from ``jnt_range`` (rad or m). MuJoCo rotates a body about an axis through the joint's
  ``pos`` and lets a body carry several joints, applied in order. With the joint anchors
  :math:`p_k` and axes :math:`a_k` in the body frame,

  .. math:: T_{parent,body} = B \\prod_k \\mathrm{Tr}(p_k)\\, M(a_k, q_k - q_{0,k})\\, \\mathrm{Tr}(-p_k)

  where ``B`` is the compiled body pose and ``q0`` the joint's ``ref``. Joint k therefore moves
  a virtual link ``<body>__<joint>`` with origin :math:`\\mathrm{Tr}(p_k - p_{k-1})` and the ref
  folded in (rotations and translations about one axis commute); the body follows on a fixed
  joint ``<body>__anchor`` with origin :math:`\\mathrm{Tr}(-p_n)`. When the last anchor is the
  body origin, the body itself is the last joint's child. This reproduces ``mj_kinematics``
  exactly. An unnamed joint is called ``<body>__joint<k>``.
* **Free joints.** A free joint on a body whose parent is the world is dropped: the body is
  welded to the world at its compiled initial pose (``qpos0``, i.e. the pose in the file). Place
  a free-flying robot with ``T_world_base`` instead. Free joints elsewhere and ball joints raise
  :class:`ModelError` (valid: hinge, slide).
* **Equality constraints.** An active ``<equality><joint>`` with a linear polynomial
  (``polycoef`` a0, a1, 0, 0, 0) makes ``joint1`` a mimic of ``joint2``:
  :math:`q_1 = a_1 q_2 + a_0 + q_{0,1} - a_1 q_{0,2}`; one without ``joint2`` locks ``joint1``
  at :math:`a_0 + q_{0,1}` (it becomes fixed). Non-linear couplings raise :class:`ModelError`.
  Other equality types (connect, weld, tendon) are not kinematic-tree facts and are ignored.
* **Geoms.** Every geom is a visual; geoms that take part in contacts (``contype`` or
  ``conaffinity`` non-zero) are also collision geometry. Box half sizes become full sizes;
  capsule and cylinder half-lengths become full lengths; meshes are read from the compiled
  ``mesh_vert``/``mesh_face`` (MuJoCo re-centres and re-orients them and moves the offset into
  the geom pose); ellipsoids become in-memory meshes. Planes, height fields and SDF geoms have
  no finite primitive here and are skipped (logged).
* **Sites** become frame links fixed to their body, named like the site (``<body>__site<k>``
  when unnamed or when the name is taken by a body).
* **Collision pairs.** A body and its parent body are never checked against each other,
  whatever the joints between them (MuJoCo's ``filterparent``): disabled collision pairs.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from prehensile.errors import ModelError
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.model.xml_utils import parse_xml
from prehensile.spatial import axis_angle_to_matrix, make_pose, quaternion_to_matrix

log = logging.getLogger(__name__)

_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_PLANE, _HFIELD, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = range(8)
_EQ_JOINT = 2
_TYPE_NAMES = {_FREE: "free", _BALL: "ball", _SLIDE: "slide", _HINGE: "hinge"}


def _name(mj, obj, index: int, fallback: str) -> str:
    import mujoco

    return mujoco.mj_id2name(mj, obj, index) or fallback


def _translation(p: np.ndarray) -> np.ndarray:
    return make_pose(position=np.asarray(p, dtype=float))


def _geometry(mj, g: int, source: str, body: str) -> Geometry | None:
    import mujoco

    kind = int(mj.geom_type[g])
    size = mj.geom_size[g]
    name = _name(mj, mujoco.mjtObj.mjOBJ_GEOM, g, "")
    if kind == _BOX:
        shape = Box(tuple(float(2.0 * s) for s in size))
    elif kind == _SPHERE:
        shape = Sphere(float(size[0]))
    elif kind == _CAPSULE:
        shape = Capsule(float(size[0]), float(2.0 * size[1]))
    elif kind == _CYLINDER:
        shape = Cylinder(float(size[0]), float(2.0 * size[1]))
    elif kind == _ELLIPSOID:
        import trimesh

        sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        shape = Mesh.from_arrays(sphere.vertices * size, sphere.faces)
    elif kind == _MESH:
        mesh = int(mj.geom_dataid[g])
        v0, nv = int(mj.mesh_vertadr[mesh]), int(mj.mesh_vertnum[mesh])
        f0, nf = int(mj.mesh_faceadr[mesh]), int(mj.mesh_facenum[mesh])
        shape = Mesh.from_arrays(mj.mesh_vert[v0:v0 + nv], mj.mesh_face[f0:f0 + nf])
    else:
        kinds = {_PLANE: "plane", _HFIELD: "hfield"}
        log.info("%s: body '%s' geom '%s' of type %s skipped (no finite shape)", source, body, name,
                 kinds.get(kind, f"#{kind}"))
        return None
    T = make_pose(quaternion_to_matrix(mj.geom_quat[g]), mj.geom_pos[g])
    return Geometry(shape, T, name)


def _equalities(mj, source: str) -> dict[int, tuple[int, float, float]]:
    """joint id -> (leader joint id or -1, multiplier, offset) from active joint equalities."""
    import mujoco

    active = getattr(mj, "eq_active0", np.ones(mj.neq, dtype=bool))
    couplings: dict[int, tuple[int, float, float]] = {}
    for e in range(mj.neq):
        if int(mj.eq_type[e]) != _EQ_JOINT or not active[e]:
            continue
        j1, j2 = int(mj.eq_obj1id[e]), int(mj.eq_obj2id[e])
        a = np.asarray(mj.eq_data[e][:5], dtype=float)
        name = _name(mj, mujoco.mjtObj.mjOBJ_EQUALITY, e, f"#{e}")
        if np.any(a[2:] != 0.0):
            raise ModelError(
                f"{source}: <equality><joint> '{name}' has a non-linear polycoef {a.tolist()}; "
                "only linear couplings (a0 a1 0 0 0) can become mimic joints"
            )
        q1 = float(mj.qpos0[mj.jnt_qposadr[j1]])
        if j2 < 0:
            couplings[j1] = (-1, 0.0, a[0] + q1)
        else:
            q2 = float(mj.qpos0[mj.jnt_qposadr[j2]])
            couplings[j1] = (j2, a[1], a[0] + q1 - a[1] * q2)
    return couplings


def _motion(kind: int, axis: np.ndarray, value: float) -> np.ndarray:
    if kind == _HINGE:
        return make_pose(axis_angle_to_matrix(axis, value))
    return _translation(axis * value)


def _add_sites(mj, body_names: list[str], links: list[LinkSpec], joints: list[JointSpec]) -> None:
    """Each site becomes a frame link fixed to its body (``<body>__site<k>`` if unnamed or if
    its name is taken), so TCPs and sensor frames defined as sites can be used as links."""
    import mujoco

    taken = {link.name for link in links}
    for s in range(mj.nsite):
        body = body_names[int(mj.site_bodyid[s])]
        name = _name(mj, mujoco.mjtObj.mjOBJ_SITE, s, "")
        if not name or name in taken:
            name = f"{body}__site{s}"
        taken.add(name)
        links.append(LinkSpec(name))
        T = make_pose(quaternion_to_matrix(mj.site_quat[s]), mj.site_pos[s])
        joints.append(JointSpec(f"{name}__site", "fixed", body, name, T, where=f"site '{name}'"))


def _compile(path: Path, source: str):
    import mujoco

    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception as err:  # mujoco raises ValueError with its compiler message
        message = " ".join(str(err).split())
        raise ModelError(f"{source}: MuJoCo could not compile the model: {message}") from None


def load_mjcf(path: str | Path) -> RobotModel:
    """Load an MJCF file through MuJoCo's compiler.

    Args:
        path: the ``.xml`` file (root element ``<mujoco>``).

    Returns:
        The robot model; link names are body names, the root link is ``world``.

    Raises:
        ModelError: missing or malformed file, MuJoCo compile errors (with MuJoCo's message),
            ball joints or non-root free joints, non-linear joint equalities; the message names
            the file.
    """
    import mujoco

    path = Path(path)
    source = str(path)
    root = parse_xml(path)
    if root.tag != "mujoco":
        raise ModelError(f"{source}: root element is <{root.tag}>, expected <mujoco>")
    mj = _compile(path, source)
    couplings = _equalities(mj, source)
    body_names = [_name(mj, mujoco.mjtObj.mjOBJ_BODY, b, "world" if b == 0 else f"body{b}")
                  for b in range(mj.nbody)]
    joint_names = {}
    links = [LinkSpec(body_names[0])]
    joints: list[JointSpec] = []
    parent_pairs: list[tuple[str, str]] = []  # (parent body, body): collision pairs MuJoCo never tests
    for b in range(mj.nbody):
        spec = links[-1] if b == 0 else LinkSpec(body_names[b])
        for g in range(mj.ngeom):
            if int(mj.geom_bodyid[g]) != b:
                continue
            geom = _geometry(mj, g, source, body_names[b])
            if geom is not None:
                spec.visuals.append(geom)
                if mj.geom_contype[g] or mj.geom_conaffinity[g]:
                    spec.collisions.append(geom)
        if b == 0:
            continue
        links.append(spec)
        body = body_names[b]
        parent = body_names[int(mj.body_parentid[b])]
        if int(mj.body_parentid[b]) != 0:  # MuJoCo's filterparent: a body never collides with its parent
            parent_pairs.append((parent, body))
        B = make_pose(quaternion_to_matrix(mj.body_quat[b]), mj.body_pos[b])
        first, count = int(mj.body_jntadr[b]), int(mj.body_jntnum[b])
        ids = list(range(first, first + count)) if count > 0 else []
        kinds = [int(mj.jnt_type[j]) for j in ids]
        if kinds and kinds[0] == _FREE and int(mj.body_parentid[b]) == 0:
            ids = []  # a free-flying root: welded at its initial pose, see the module docstring
        for j, kind in zip(ids, kinds):
            if kind not in (_HINGE, _SLIDE):
                raise ModelError(
                    f"{source}: body '{body}' has a {_TYPE_NAMES.get(kind, kind)} joint "
                    f"'{_name(mj, mujoco.mjtObj.mjOBJ_JOINT, j, '')}'; valid joint types: hinge, slide "
                    "(a free joint is accepted only on a body attached to the world)"
                )
        if not ids:
            joints.append(JointSpec(f"{body}__weld", "fixed", parent, body, B, where=f"body '{body}'"))
            continue
        previous = parent
        anchor_prev = np.zeros(3)
        for k, j in enumerate(ids):
            name = _name(mj, mujoco.mjtObj.mjOBJ_JOINT, j, f"{body}__joint{k}")
            joint_names[j] = name
            kind, axis = int(mj.jnt_type[j]), np.asarray(mj.jnt_axis[j], dtype=float)
            anchor = np.asarray(mj.jnt_pos[j], dtype=float)
            last = k == len(ids) - 1
            child = body if last and not np.any(anchor) else f"{body}__{name}"
            if child != body:
                links.append(LinkSpec(child))
            origin = _translation(anchor - anchor_prev) @ _motion(kind, axis, -float(mj.qpos0[mj.jnt_qposadr[j]]))
            if k == 0:
                origin = B @ origin
            limited = bool(mj.jnt_limited[j])
            jtype = "prismatic" if kind == _SLIDE else ("revolute" if limited else "continuous")
            lower, upper = (float(v) for v in mj.jnt_range[j]) if limited else (None, None)
            joints.append(JointSpec(name, jtype, previous, child, origin, axis, lower, upper,
                                    where=f"body '{body}' joint '{name}'"))
            previous, anchor_prev = child, anchor
        if previous != body:
            joints.append(JointSpec(f"{body}__anchor", "fixed", previous, body, _translation(-anchor_prev),
                                    where=f"body '{body}'"))
    _add_sites(mj, body_names, links, joints)
    by_name = {spec.name: spec for spec in joints}
    for j, (leader, multiplier, offset) in couplings.items():
        if j not in joint_names or (leader >= 0 and leader not in joint_names):
            raise ModelError(f"{source}: a joint equality couples a joint that is not a hinge or slide joint")
        spec = by_name[joint_names[j]]
        if leader < 0:
            spec.T_parent_joint = spec.T_parent_joint @ _motion(int(mj.jnt_type[j]), spec.axis, offset)
            spec.type = "fixed"
        else:
            spec.mimic = (joint_names[leader], multiplier, offset)
    name = root.get("model") or path.stem
    return build_model(name, source, links, joints, disabled_collision_pairs=parent_pairs)
