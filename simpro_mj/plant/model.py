"""Loading, perturbing and inspecting the MuJoCo model of the platform.

One entry point, :func:`load_model`, reads ``models/simpro_platform.xml``
(package data) and applies parameter overrides with :class:`mujoco.MjSpec` (payload, as-built
attachment-point errors, guide dimensions), so that a scenario's plant can
differ from the controller's nominal model. :func:`assemble` then finds the
closed-loop configuration for given slide positions (the loops of a
perturbed model do not close at ``qpos0``).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simpro_mj.core.errors import PhysicsError, UserInputError
from simpro_mj.core.keys import closest
from simpro_mj.core.messages import one_line
from simpro_mj.core.shipped import MODEL_DIR, model_path
from simpro_mj.plant.model_params import (
    BASE_POINTS,
    DEFAULT_MODEL_PARAMS,
    LEG_POINTS,
    MAX_MODEL_PAYLOAD_KG,
    inertia_tensor,
)
from simpro_mj.plant.step_functions import platform_pose

#: The shipped model; ``SIMPRO_MODEL`` in the environment points elsewhere
#: (:func:`simpro_mj.core.shipped.model_path`, checked when a model is loaded).
MODEL_PATH = MODEL_DIR / "simpro_platform.xml"

#: A scenario's ``plant`` may name the preset its values came from
#: (:mod:`simpro_mj.config.presets`); the model itself ignores the name.
PRESET_KEY = "preset"

#: The model's scalars: dotted path, the test a value passes, what is allowed.
_SCALARS = (
    ("payload.mass_kg", lambda v: v >= 0.0, ">= 0 kg, finite"),
    ("platform_mass_kg", lambda v: v > 0.0, "> 0 kg, finite"),
    ("loop_timeconst_s", lambda v: v > 0.0, "> 0 s, finite"),
    ("guide.radius_offset_mm", lambda v: v > -1000.0, "> -1000 mm, finite"),
    # a heavy payload is refused with its limit by simpro_mj.analysis.preflight first
    ("payload.mass_kg", lambda v: v <= MAX_MODEL_PAYLOAD_KG, "<= 1e5 kg"),
)


def _at(tree: Any, path: str) -> Any:
    for part in path.split("."):
        tree = tree[part]
    return tree


def _vec(tree: dict, path: str, n: int, where: str = "model") -> np.ndarray:
    """The ``n`` finite numbers at ``path`` of ``tree``; a one-line refusal otherwise."""
    try:
        arr = np.asarray(_at(tree, path), dtype=float)
    except (KeyError, TypeError, ValueError):
        arr = np.empty(0)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise UserInputError(
            f"invalid value at {where}.{path}: expected a list of {n} finite numbers"
        )
    return arr


def _check_params(params: dict) -> None:
    anchors = DEFAULT_MODEL_PARAMS["anchor_offsets_mm"]
    for where, given, known in (
        ("", set(params) - {PRESET_KEY}, DEFAULT_MODEL_PARAMS),
        ("anchor_offsets_mm.", params["anchor_offsets_mm"], anchors),
    ):
        unknown = sorted(set(given) - set(known))
        if unknown:
            raise UserInputError(
                f"unknown key at model.{where}{unknown[0]}: allowed keys are {sorted(known)}"
                f"{closest(unknown[0], known)}"
            )
    for path, ok, allowed in _SCALARS:
        v = _at(params, path)
        if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v) or not ok(v):
            raise UserInputError(f"invalid value at model.{path}: {v!r}; allowed: {allowed}")


#: What :func:`load_spec` edits, so what an MJCF given as ``SIMPRO_MODEL`` must name.
_REQUIRED = {
    "body": ("payload", "guide_upper", "guide_lower", "bracket")
    + tuple(f"leg{i}_barrel" for i in (1, 2, 3)),
    "geom": ("payload", "platform_frame", "guide_upper", "guide_lower"),
    "joint": ("leg1", "leg2", "leg3"),
    "site": (*BASE_POINTS, *LEG_POINTS, "guide_lower_tip"),
}


def _read_spec(path) -> mujoco.MjSpec:
    """The MJCF at ``path`` (default :func:`~simpro_mj.core.shipped.model_path`), parsed;
    a file MuJoCo cannot read, or an MJCF of another machine, is a one-line refusal
    naming ``SIMPRO_MODEL``."""
    where = str(path or model_path())
    try:
        spec = mujoco.MjSpec.from_file(where)
    except ValueError as exc:
        raise UserInputError(
            f"invalid value at SIMPRO_MODEL: {where}: {one_line(str(exc))[:300]}; allowed: "
            "the SIMPRO platform's MJCF (models/simpro_platform.xml or an edited copy)"
        ) from None
    for kind, names in _REQUIRED.items():
        missing = [n for n in names if getattr(spec, kind)(n) is None]
        if missing:
            raise UserInputError(
                f"invalid value at SIMPRO_MODEL: {where}: no {kind} {', '.join(missing)}; "
                "allowed: the SIMPRO platform's MJCF (models/simpro_platform.xml or an "
                "edited copy)"
            )
    return spec


def load_spec(params: dict | None = None, path: Path | str | None = None) -> mujoco.MjSpec:
    """The model as an :class:`mujoco.MjSpec` with the parameters applied."""
    p = copy.deepcopy(DEFAULT_MODEL_PARAMS) if params is None else params
    _check_params(p)
    spec = _read_spec(path)

    payload = spec.body("payload")
    payload.pos = _vec(p, "payload.com_mm", 3) * 1e-3
    # mass 0 would make the payload body massless: MuJoCo needs a tiny mass there
    mass = max(float(p["payload"]["mass_kg"]), 1e-6)
    spec.geom("payload").mass = mass
    inertia = p["payload"].get("inertia_kg_m2")
    if inertia is not None:
        # the given inertia instead of the box geom's: the payload body's own inertial
        # (inertiafromgeom "auto" reads geoms only for bodies without one, as the others)
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
        payload.explicitinertial = True
        payload.mass, payload.ipos = mass, [0.0, 0.0, 0.0]
        ref_mass = p["payload"].get("inertia_mass_kg")  # set: the same cabin, inertia ~ mass
        scale = 1.0 if ref_mass is None else mass / float(ref_mass)
        payload.fullinertia = [scale * v for v in inertia_tensor(inertia)]
    spec.geom("platform_frame").mass = float(p["platform_mass_kg"])
    if p.get("rig") is not None:
        apply_rig(spec, p["rig"])

    for name in BASE_POINTS + LEG_POINTS:
        off = _vec(p, f"anchor_offsets_mm.{name}", 3) * 1e-3
        spec.site(name).pos = np.asarray(spec.site(name).pos) + off
        if name in BASE_POINTS:  # the leg's barrel sits on its base anchor
            body = spec.body(f"leg{name[1]}_barrel")
            body.pos = np.asarray(body.pos) + off

    dr = float(p["guide"]["radius_offset_mm"]) * 1e-3
    dc = _vec(p, "guide.centre_offset_mm", 2) * 1e-3
    if dr or np.any(dc):
        upper, lower = spec.body("guide_upper"), spec.body("guide_lower")
        tip = np.asarray(spec.body("bracket").pos, dtype=float)  # link vector at home
        r0 = np.linalg.norm(tip)
        if r0 + dr <= 0.1:
            raise UserInputError(
                "invalid value at model.guide.radius_offset_mm: the guide radius must stay > 100 mm"
            )
        new_tip = tip * (r0 + dr) / r0
        for body in (upper, lower):
            body.pos = np.asarray(body.pos) + np.array([dc[0], 0.0, dc[1]])
        spec.body("bracket").pos = new_tip
        spec.site("guide_lower_tip").pos = new_tip
        for gname in ("guide_upper", "guide_lower"):
            spec.geom(gname).fromto = np.concatenate([[0.0, 0.0, 0.0], new_tip])

    tc = float(p["loop_timeconst_s"])
    for eq in spec.equalities:
        eq.solref = [tc, 1.0]
    return spec


def apply_rig(spec: mujoco.MjSpec, rig: dict) -> None:
    """Rebuild the MJCF's geometry from a rig record (:mod:`simpro_mj.config.rig`, mm).

    The same record gives the controllers' geometry
    (:func:`controllers.geometry.geometry_from_rig`), so both follow one source. At the
    home pose: P = (0, 0, B1_z); the base sites and mounts at A_i; the guide's upper
    pivot at the arc's centre B1 + ``guide_centre_from_b1_mm``, the lower one at that
    centre + (C2 - B1) (the parallelogram); the bracket's sites at B1, C1, C2; the
    platform's B2, B3 at B_i - P; each leg's barrel at A_i along A_i -> its
    attachment, its rod's tip at the home length, the slide's range the stroke and its
    reference the home stroke.
    """
    if not isinstance(rig, dict):
        raise UserInputError(
            f"wrong type at model.rig: got {type(rig).__name__}; allowed: null or a rig "
            "record (simpro_mj.config.rig reads a rig file)"
        )

    def point(path):
        return _vec(rig, path, 3, "model.rig") / 1000.0

    a = [point(f"base_anchors_mm.A{i}") for i in (1, 2, 3)]
    b1, b2, b3 = (point(f"platform_anchors_mm.B{i}") for i in (1, 2, 3))
    c1, c2 = point("bracket_mm.C1"), point("bracket_mm.C2")
    dx, dz = (float(v) / 1000.0 for v in rig["guide_centre_from_b1_mm"])
    stroke, q_home = float(rig["stroke_mm"]) / 1000.0, float(rig["home_stroke_mm"]) / 1000.0
    p_home = np.array([0.0, 0.0, b1[2]])
    pivot = b1 + np.array([dx, 0.0, dz])
    for i, ai in enumerate(a, start=1):
        spec.site(f"A{i}").pos = ai
        spec.geom(f"mount_A{i}").pos = ai + np.array([0.0, 0.0, 0.03])
    link = b1 - pivot  # pivot -> bracket, both links of the parallelogram
    spec.body("guide_upper").pos = pivot
    spec.body("guide_lower").pos = pivot + (c2 - b1)
    spec.body("bracket").pos = link
    spec.site("guide_lower_tip").pos = link
    for gname in ("guide_upper", "guide_lower"):
        spec.geom(gname).fromto = np.concatenate([[0.0, 0.0, 0.0], link])
    half = max(pivot[2] + 0.015, 0.02) / 2  # the post's top 15 mm above the pivot
    spec.geom("guide_post").pos = [pivot[0], 0.0, half]
    spec.geom("guide_post").size = [0.06, 0.08, half]
    spec.site("C1").pos, spec.site("C2").pos = c1 - b1, c2 - b1
    spec.geom("bracket_b1c2").fromto = np.concatenate([[0.0, 0.0, 0.0], c2 - b1])
    spec.geom("bracket_c2c1").fromto = np.concatenate([c2 - b1, c1 - b1])
    spec.body("platform").pos = p_home - b1
    for jname in ("pitch", "roll"):
        spec.joint(jname).pos = b1 - p_home
    spec.site("B2").pos, spec.site("B3").pos = b2 - p_home, b3 - p_home
    for i, (ai, attach) in enumerate(zip(a, (c1, b2, b3), strict=True), start=1):
        leg = attach - ai
        length = float(np.linalg.norm(leg))
        barrel = spec.body(f"leg{i}_barrel")
        barrel.pos = ai
        barrel.alt.type = mujoco.mjtOrientation.mjORIENTATION_ZAXIS
        barrel.alt.zaxis = leg / length
        slide = spec.joint(f"leg{i}")
        slide.range = [0.0, stroke]
        slide.ref = q_home
        # the rod's geom keeps its offset from the tip (the shipped MJCF's 330 mm)
        spec.geom(f"leg{i}_rod").pos = [0.0, 0.0, length - 0.33]
        spec.site(f"leg{i}_tip").pos = [0.0, 0.0, length]


def add_slide_drives(spec: mujoco.MjSpec) -> None:
    """Add one joint-equality constraint per slide (``drive1..3``) to impose q.

    They are as stiff as the loop closures (same solref/solimp). Set the target
    at run time with ``model.eq_data[id, 0] = q - model.qpos0[slide]`` (a joint
    equality acts on ``qpos - qpos0``).
    """
    ref = spec.equalities[0]
    for i in (1, 2, 3):
        spec.add_equality(
            type=mujoco.mjtEq.mjEQ_JOINT,
            name=f"drive{i}",
            name1=f"leg{i}",
            objtype=mujoco.mjtObj.mjOBJ_JOINT,
            solref=list(ref.solref),
            solimp=list(ref.solimp),
        )


def load_model(params: dict | None = None, path: Path | str | None = None) -> mujoco.MjModel:
    """Compile the platform model with parameter overrides.

    Parameters
    ----------
    params : dict, optional
        A tree like :data:`~simpro_mj.plant.model_params.DEFAULT_MODEL_PARAMS` (use
        :func:`~simpro_mj.core.keys.apply_overrides` to apply ``--set`` expressions to
        it). ``None``: the nominal model.
    path : path, optional
        Another MJCF file (default :data:`MODEL_PATH`).

    Raises
    ------
    UserInputError
        For unknown keys or invalid values (the message names the field).
    """
    spec = load_spec(params, path)
    model = spec.compile()
    if model.opt.timestep <= 0:
        raise UserInputError("invalid model: timestep must be > 0")
    return model


@dataclass(frozen=True)
class PlantIndex:
    """Index arrays into ``qpos``/``qvel``/``ctrl``/``sensordata`` (precomputed once)."""

    slide_qpos: np.ndarray
    slide_dof: np.ndarray
    actuators: np.ndarray
    site_p: int
    connect_sites: np.ndarray  # (n_loops, 2) site ids
    loop_names: tuple
    sensor: dict  # sensor name -> slice into sensordata

    @classmethod
    def of(cls, model: mujoco.MjModel) -> PlantIndex:
        slides = [model.joint(f"leg{i}") for i in (1, 2, 3)]
        pairs, names = [], []
        for k in range(model.neq):
            if model.eq_type[k] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[k] == int(
                mujoco.mjtObj.mjOBJ_SITE
            ):
                pairs.append((model.eq_obj1id[k], model.eq_obj2id[k]))
                names.append(model.eq(k).name)
        sensor = {}
        for s in range(model.nsensor):
            adr, dim = model.sensor_adr[s], model.sensor_dim[s]
            sensor[model.sensor(s).name] = slice(int(adr), int(adr + dim))
        return cls(
            slide_qpos=np.array([j.qposadr[0] for j in slides]),
            slide_dof=np.array([j.dofadr[0] for j in slides]),
            actuators=np.array([model.actuator(f"leg{i}").id for i in (1, 2, 3)]),
            site_p=model.site("P").id,
            connect_sites=np.array(pairs, dtype=int).reshape(-1, 2),
            loop_names=tuple(names),
            sensor=sensor,
        )


def loop_closure_error(model: mujoco.MjModel, data: mujoco.MjData, index=None) -> np.ndarray:
    """Distance (m) between the two sites of each loop-closing ``connect``.

    Uses ``data.site_xpos``, so it is valid after ``mj_step``/``mj_kinematics``.
    Returns one value per loop (``PlantIndex.loop_names``); take ``.max()``
    for the worst.
    """
    idx = index or PlantIndex.of(model)
    s = idx.connect_sites
    return np.linalg.norm(data.site_xpos[s[:, 0]] - data.site_xpos[s[:, 1]], axis=1)


def loop_closure_jacobian(model, data, index=None) -> tuple[np.ndarray, np.ndarray]:
    """Residual (3L,) and Jacobian (3L, nv) of the loop-closure equations."""
    idx = index or PlantIndex.of(model)
    jp1, jp2 = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    res, jac = [], []
    for a, b in idx.connect_sites:
        mujoco.mj_jacSite(model, data, jp1, None, int(a))
        mujoco.mj_jacSite(model, data, jp2, None, int(b))
        res.append(data.site_xpos[a] - data.site_xpos[b])
        jac.append(jp1 - jp2)
    return np.concatenate(res), np.vstack(jac)


def mobility(model, data, hold_slides: bool = False, tol: float = 1e-9) -> int:
    """Degrees of freedom of the closed chain at the current configuration.

    ``nv - rank(J)`` with J the loop-closure Jacobian (plus unit rows for the
    slide joints when ``hold_slides``). Redundant rows (planar loops closed
    with 3-D connects) are handled by the numerical rank.
    """
    idx = PlantIndex.of(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    _, jac = loop_closure_jacobian(model, data, idx)
    if hold_slides:
        rows = np.zeros((3, model.nv))
        rows[np.arange(3), idx.slide_dof] = 1.0
        jac = np.vstack([jac, rows])
    sv = np.linalg.svd(jac, compute_uv=False)
    rank = int(np.sum(sv > tol * max(sv.max(), 1.0)))
    return model.nv - rank


def assemble(
    model, data, q_slides=None, tol: float = 1e-12, max_iter: int = 50, index=None
) -> float:
    """Close the loops by Newton iteration with the slides held at ``q_slides``.

    Starts from ``data.qpos`` and moves all joints (least-norm steps) until the
    loop-closure residual is below ``tol`` (m). ``q_slides`` defaults to the
    current slide positions. Velocities are zeroed. Returns the final residual.

    Raises
    ------
    PhysicsError
        If the loops cannot be closed (slides outside the assemblable range).
    """
    idx = index or PlantIndex.of(model)
    if q_slides is not None:
        data.qpos[idx.slide_qpos] = q_slides
    target = data.qpos[idx.slide_qpos].copy()
    sel = np.zeros((3, model.nv))
    sel[np.arange(3), idx.slide_dof] = 1.0
    res = np.inf
    for _ in range(max_iter):
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        r, jac = loop_closure_jacobian(model, data, idx)
        r = np.concatenate([r, data.qpos[idx.slide_qpos] - target])
        jac = np.vstack([jac, sel])
        res = float(np.max(np.abs(r)))
        if res < tol:
            break
        dq = -np.linalg.lstsq(jac, r, rcond=None)[0]
        mujoco.mj_integratePos(model, data.qpos, dq, 1.0)
    else:
        if res > 1e-8:
            raise PhysicsError(
                f"cannot assemble the closed chain at q = {np.round(target * 1e3, 2)} mm "
                f"(loop residual {res:.2e} m)"
            )
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    return res


def measured_pose(data, site_p: int) -> np.ndarray:
    """(roll, pitch, h) of the platform frame from MuJoCo, eq. (8) inverted: the
    step's own read (:func:`simpro_mj.plant.step_functions.platform_pose`)."""
    pose = np.empty(3)
    xmat, xpos = data.site_xmat.reshape(-1), data.site_xpos.reshape(-1)
    platform_pose(xmat, xpos, 9 * int(site_p), 3 * int(site_p) + 2, pose)
    return pose


def check_physics(model, data, warnings_before=None, loop_bound: float | None = None, index=None):
    """Raise :class:`PhysicsError` on divergence after a step.

    Checks, in order: MuJoCo warning counters that grew since
    ``warnings_before`` (from ``data.warning.number.copy()``), non-finite
    ``qpos``/``qvel``, and loop-closure error above ``loop_bound`` (m).
    """
    counts = data.warning.number
    if warnings_before is not None and np.any(counts > warnings_before):
        k = int(np.flatnonzero(counts > warnings_before)[0])
        raise PhysicsError(
            f"MuJoCo warning {mujoco.mjtWarning(k).name} at t = {data.time:.3f} s "
            f"(info {data.warning.lastinfo[k]})"
        )
    if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        bad = np.flatnonzero(~np.isfinite(data.qpos))
        which = (
            model.joint(int(np.searchsorted(model.jnt_qposadr, bad[0], "right") - 1)).name
            if bad.size
            else "qvel"
        )
        raise PhysicsError(f"non-finite state ({which}) at t = {data.time:.3f} s")
    if loop_bound is not None:
        err = loop_closure_error(model, data, index)
        if err.max() > loop_bound:
            idx = index or PlantIndex.of(model)
            k = int(err.argmax())
            raise PhysicsError(
                f"kinematic loop '{idx.loop_names[k]}' opened: closure error "
                f"{err[k] * 1e3:.3f} mm > bound {loop_bound * 1e3:.3f} mm at t = {data.time:.3f} s"
            )
