"""MuJoCo peer model of RRRobot, for side-by-side comparison with the numpy simulator.

The robot is the one pinned down in ``MODEL.md``: a massless hemispherical shell
of radius r with five point masses (Mb at the bottom, Ms at each leg pin, Ml at
each leg tip) and two massless legs of length l turning about the body Y axis.
Two models are built:

``"pivot"``  (Pivoting Dynamics)
    The shell hangs on a ball joint at the sphere centre, fixed in the world.
    The contact point is predicted kinematically, ``xdot = r w_y``,
    ``ydot = -r w_x`` (w = world-frame angular velocity), integrated outside
    MuJoCo with the trapezoidal rule.
``"plane"``  (RRRobot on a plane)
    A free joint; a sphere geom of radius r rolls on a plane. MuJoCo contacts are
    soft, so rolling without slip is only approximated; see ``build_mjcf`` for
    the contact settings and ``MujocoRobot.slip`` for a measure of the slip.

``mujoco`` is an optional dependency (the project's ``bench`` extra, or
``pip install mujoco``); it is imported inside the functions that need it.

Conventions (MODEL.md): body frame at the sphere centre, z up when upright;
leg 1 pinned at (0, -r, 0), leg 2 at (0, +r, 0); the leg tip of leg k is at
(l cos phi_k, -/+r, l sin phi_k). The quaternion returned is MuJoCo's
(w, x, y, z), body -> world.

Example::

    from benchmarks.mujoco_peer import MujocoRobot
    rob = MujocoRobot("pivot")
    out = rob.step_gait(1, 50.0)
    print(out["x"][-1], out["y"][-1])
"""

from __future__ import annotations

import math
import time as _time
from typing import Any, Dict, Optional, Sequence, Union

import numpy as np

__all__ = [
    "GAITS",
    "build_mjcf",
    "compile_model",
    "gait_targets",
    "gait_controls",
    "MujocoRobot",
    "rollout_batch",
    "contact_xy_from_states",
    "settle_height",
]

# Table II of the paper: phi_k(t) = a sin(w t + beta_k) + gamma.
GAITS: Dict[int, Dict[str, Any]] = {
    1: dict(a=0.3, w=8.0, beta=(0.0, math.pi / 2), gamma=math.pi / 2),
    2: dict(a=0.3, w=8.0, beta=(0.0, math.pi / 2), gamma=0.0),
    3: dict(a=0.3, w=8.0, beta=(0.0, math.pi / 2), gamma=math.pi / 4),
}

MODELS = ("pivot", "plane")


def _import_mujoco():
    try:
        import mujoco  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "benchmarks.mujoco_peer needs the optional dependency 'mujoco': "
            "pip install mujoco   (or install the project's 'bench' extra)"
        ) from exc
    return mujoco


# ---------------------------------------------------------------------------
# MJCF
# ---------------------------------------------------------------------------

def build_mjcf(
    model: str,
    *,
    radius: float = 0.12,
    leg_length: float = 0.1,
    mass_bottom: float = 0.3,
    mass_pin: float = 0.053,
    mass_tip: float = 0.057,
    gravity: float = 9.81,
    damping: float = -0.01,
    timestep: float = 0.001,
    integrator: str = "RK4",
    kp: float = 2.0,
    kd: float = 0.05,
    point_inertia: float = 1e-10,
    friction: float = 10.0,
    solref: Sequence[float] = (0.004, 0.3),
    solimp: Sequence[float] = (0.99, 0.999, 0.001, 0.5, 2.0),
    impratio: float = 100.0,
    noslip_iterations: int = 50,
    noslip_tolerance: float = 1e-10,
    cone: str = "elliptic",
    tolerance: float = 1e-10,
    iterations: int = 100,
) -> str:
    """Return the MJCF XML of RRRobot, ``model`` = ``"pivot"`` or ``"plane"``.

    Masses, geometry, gravity, ``timestep`` and ``integrator`` go straight into
    the XML. The other choices:

    Point masses
        ``compiler inertiafromgeom="false"``: geoms never contribute mass; every
        point mass is a body of its own (welded to its parent, i.e. without a
        joint) with an ``<inertial>`` of the given mass and a negligible
        ``diaginertia`` (``point_inertia``, 1e-10 kg m^2 against the robot's
        ~4e-3 kg m^2). The shell and leg bodies carry no mass of their own.
        Joints have no armature, damping (except the body damping below),
        stiffness or frictionloss: MuJoCo's defaults are all zero, and they are
        written out explicitly anyway.

    Legs
        Hinges with axis -Y in the body frame, so that phi increasing turns the
        tip from +X toward +Z (a rotation by phi about -Y maps +X to
        (cos phi, 0, sin phi)). The leg bodies are drawn in the vertical pose
        and the hinges have ``ref = pi/2``: qpos of the hinge *is* phi, and
        ``qpos0`` (what ``mj_resetData`` restores) has both legs vertical.

    Body damping
        The paper's torque ``k w`` (k < 0 dissipates) with w the world-frame
        angular velocity. MuJoCo joint damping d on a ball joint applies
        ``-d * qvel`` where qvel is the angular velocity in the *body* frame;
        mapped to the world frame that torque is ``-d R w_body = -d w``, the same
        vector, because the damping is isotropic. So ``d = -k``. For the free
        joint the same holds for its three angular dofs, but MJCF only takes a
        single damping value for all six dofs of a free joint, which would also
        damp the translation of the centre. ``compile_model`` therefore sets the
        three translational ``dof_damping`` entries back to zero after
        compiling; the XML carries a comment saying so. Compile the plane XML
        through ``compile_model`` (``MujocoRobot`` and ``rollout_batch`` do).
        With ``integrator="RK4"`` the damping is integrated explicitly like any
        other force (|d| = 0.01 is far from any stability limit).

    Leg servo
        tau = kp (phi_d - phi) + kd (phid_d - phidot), as two actuators per leg:
        a ``position`` actuator (gain kp, no kv) whose control is phi_d and a
        ``velocity`` actuator (gain kd) whose control is phid_d. Control vector
        ``ctrl = (phi_d1, phi_d2, phid_d1, phid_d2)``. Controls, force ranges
        are unlimited. MuJoCo holds ``ctrl`` constant over one ``mj_step``
        (zero-order hold, also across the four RK4 stages), so a target sampled
        at the start of the step lags a continuous-time servo by dt/2 on
        average; ``gait_controls`` samples at the step midpoint by default.
        The servo is integrated explicitly under RK4. On the plane, MuJoCo's
        unconstrained dynamics see a free-floating body, so the effective
        inertia of a leg is only ~1.2e-4 kg m^2 (in-phase mode; 3.4e-4 on the
        pivot, Ml l^2 = 5.7e-4): RK4 at timestep 1e-3 goes unstable for
        kd >~ 0.3 (the default 0.05 is well inside). For stiffer servos use a
        smaller timestep or ``integrator="implicitfast"``.

    Plane contact (``model="plane"`` only)
        The only collision pair is the sphere geom with the floor plane.
        ``condim=3``: normal + two sliding friction directions; torsional and
        rolling friction do not exist at condim 3, so spinning about the
        vertical and rolling are free, which is what rolling-without-slip needs.
        Slip is suppressed by: a large sliding friction coefficient
        (``friction``; the motion needs far less than 1, so the cone never
        saturates); an ``elliptic`` cone (with pyramidal cones impratio mixes
        normal and friction); ``impratio`` >> 1, making the friction rows much
        harder than the normal row; and the NoSlip post-processing solver
        (``noslip_iterations``), which re-solves the friction rows with zero
        regularisation, removing the creep that soft friction otherwise shows.
        Normal softness: ``solref = (timeconst, dampratio) = (0.004, 0.3)``
        and ``solimp`` close to 1 (impedance 0.99..0.999). In MuJoCo the
        contact stiffness scales as 1/(timeconst * dampratio)^2 and the damping
        as 1/timeconst, so the low dampratio makes the contact stiffer (the
        sphere sinks ~1.2e-6 m under its weight, 1e-5 of r) and dissipates
        less: with tau = 0, k = 0 the plane model loses ~1e-5 J in 5 s, against
        ~3e-4 J with the critically damped (0.004, 1). timeconst >= 2 timestep
        is MuJoCo's guideline; keep ``timestep`` <= 0.002 with this solref.
        Stiffer settings, e.g. (0.002, 0.3) at timestep 5e-4, change Gait 1/3
        end points by < 2e-5 m. Solver ``tolerance`` is tightened to 1e-10.
        Pyramidal cones are a bad choice here: with friction 10 they make the
        normal direction far softer (mm of penetration).
        With ``integrator="RK4"`` MuJoCo re-runs collision and the constraint
        solver (and NoSlip) at each of the four stages.

    Units: SI, radians. ``damping`` is the paper's k (must be <= 0).
    """
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if damping > 0:
        raise ValueError("damping is the paper's k, a dissipative value is <= 0 "
                         "(MuJoCo joint damping must be non-negative)")
    r, l = float(radius), float(leg_length)
    d = -float(damping)
    pi2 = math.pi / 2
    eps = float(point_inertia)
    g = float(gravity)

    def fmt(v):
        return " ".join(repr(float(x)) for x in v)

    def point_mass(name, pos, mass):
        return (f'<body name="{name}" pos="{fmt(pos)}">'
                f'<inertial pos="0 0 0" mass="{float(mass)!r}" '
                f'diaginertia="{eps!r} {eps!r} {eps!r}"/></body>')

    plane = model == "plane"
    # damping d = -k on the root joint; no armature, stiffness or frictionloss
    passive = f'damping="{d!r}" armature="0" frictionloss="0" stiffness="0"'
    if plane:
        root_joint = (
            "<!-- free joint: qpos = (x y z, qw qx qy qz) of the sphere centre,\n"
            "           qvel = (world-frame linear velocity, body-frame angular velocity).\n"
            "           MJCF applies this damping to all 6 dofs; compile_model() resets\n"
            "           the 3 translational dof_damping entries to 0 (the damping is\n"
            "           the paper's k*w torque, on the rotation only). -->\n"
            f'      <joint name="root" type="free" {passive}/>'
        )
        shell_pos = (0.0, 0.0, r)
        contact = (f'condim="3" friction="{float(friction)!r} 0 0" '
                   f'solref="{fmt(solref)}" solimp="{fmt(solimp)}" '
                   'contype="1" conaffinity="1"')
        shell_geom = (f'<geom name="shell" type="sphere" size="{r!r}" {contact} '
                      'rgba="0.8 0.6 0.3 0.5"/>')
        floor = (f'<geom name="floor" type="plane" size="0 0 0.05" {contact} '
                 'rgba="0.5 0.5 0.5 1"/>')
        flags = '<flag energy="enable"/>'
        option_extra = (f'impratio="{float(impratio)!r}" cone="{cone}" '
                        f'noslip_iterations="{int(noslip_iterations)}" '
                        f'noslip_tolerance="{float(noslip_tolerance)!r}"')
    else:
        root_joint = (
            "<!-- ball joint at the sphere centre (world origin): qpos = quaternion\n"
            "           body->world, qvel = body-frame angular velocity -->\n"
            f'      <joint name="root" type="ball" pos="0 0 0" {passive}/>'
        )
        shell_pos = (0.0, 0.0, 0.0)
        shell_geom = (f'<geom name="shell" type="sphere" size="{r!r}" '
                      'contype="0" conaffinity="0" rgba="0.8 0.6 0.3 0.5"/>')
        floor = ""
        flags = '<flag energy="enable" contact="disable"/>'
        option_extra = ""

    def leg(k, ysign):
        # drawn vertical (phi = pi/2 = ref); tip point mass at (0, 0, l) in the leg frame
        return f"""
      <body name="leg{k}" pos="0 {ysign * r!r} 0">
        <joint name="phi{k}" type="hinge" axis="0 -1 0" pos="0 0 0" ref="{pi2!r}"
               damping="0" armature="0" frictionloss="0" stiffness="0"/>
        <geom name="leg{k}" type="capsule" fromto="0 0 0 0 0 {l!r}" size="0.005"
              contype="0" conaffinity="0" rgba="0.2 0.2 0.8 1"/>
        {point_mass(f"tip{k}", (0, 0, l), mass_tip)}
      </body>"""

    xml = f"""<mujoco model="rrrobot_{model}">
  <!-- RRRobot ({model} model), see benchmarks/mujoco_peer.py:build_mjcf -->
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{float(timestep)!r}" integrator="{integrator}" gravity="0 0 {-g!r}"
          tolerance="{float(tolerance)!r}" iterations="{int(iterations)}" {option_extra}>
    {flags}
  </option>
  <worldbody>
    {floor}
    <body name="shell" pos="{fmt(shell_pos)}">
      {root_joint}
      {shell_geom}
      {point_mass("bottom", (0, 0, -r), mass_bottom)}
      {point_mass("pin1", (0, -r, 0), mass_pin)}
      {point_mass("pin2", (0, r, 0), mass_pin)}{leg(1, -1)}{leg(2, +1)}
    </body>
  </worldbody>
  <actuator>
    <!-- ctrl = (phi_d1, phi_d2, phid_d1, phid_d2); tau = kp (phi_d - phi) + kd (phid_d - phidot) -->
    <position name="pos1" joint="phi1" kp="{float(kp)!r}"/>
    <position name="pos2" joint="phi2" kp="{float(kp)!r}"/>
    <velocity name="vel1" joint="phi1" kv="{float(kd)!r}"/>
    <velocity name="vel2" joint="phi2" kv="{float(kd)!r}"/>
  </actuator>
</mujoco>
"""
    return xml


def compile_model(model: str, **kwargs):
    """Compile ``build_mjcf(model, **kwargs)`` into an ``MjModel``.

    For the plane model this zeroes the translational damping of the free
    joint (see ``build_mjcf``: the damping is a torque on the rotation only).
    """
    mujoco = _import_mujoco()
    m = mujoco.MjModel.from_xml_string(build_mjcf(model, **kwargs))
    if model == "plane":
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "root")
        adr = m.jnt_dofadr[jid]
        m.dof_damping[adr:adr + 3] = 0.0
    return m


# ---------------------------------------------------------------------------
# gaits
# ---------------------------------------------------------------------------

def _gait_params(gait) -> Dict[str, Any]:
    if isinstance(gait, dict):
        p = dict(GAITS[1])
        p.update(gait)
        return p
    if gait not in GAITS:
        raise ValueError(f"gait must be 1, 2, 3 or a parameter dict, got {gait!r}")
    return dict(GAITS[gait])


def gait_targets(gait, t):
    """Leg targets of a Table II gait at times ``t``.

    ``gait`` is 1, 2, 3 or a dict overriding keys of gait 1 (a, w, beta, gamma).
    Returns ``(phi_d, phid_d)``, each of shape ``t.shape + (2,)``.
    """
    p = _gait_params(gait)
    t = np.asarray(t, dtype=float)[..., None]
    beta = np.asarray(p["beta"], dtype=float)
    arg = p["w"] * t + beta
    return p["a"] * np.sin(arg) + p["gamma"], p["a"] * p["w"] * np.cos(arg)


def gait_controls(gait, n_steps: int, timestep: float, *, t0: float = 0.0,
                  hold: str = "mid") -> np.ndarray:
    """Controls ``(n_steps, 4)`` for a gait, one row per ``mj_step``.

    MuJoCo holds a control over the whole step (zero-order hold). ``hold="mid"``
    samples the gait at the midpoint ``t0 + (k + 1/2) dt`` of step k, which makes
    the held target second-order accurate with respect to a continuous-time
    servo; ``hold="start"`` samples at ``t0 + k dt`` (what a naive loop does).
    """
    if hold not in ("mid", "start"):
        raise ValueError("hold must be 'mid' or 'start'")
    off = 0.5 if hold == "mid" else 0.0
    t = t0 + (np.arange(n_steps) + off) * timestep
    phi, phid = gait_targets(gait, t)
    return np.concatenate([phi, phid], axis=-1)


# ---------------------------------------------------------------------------
# helpers on states
# ---------------------------------------------------------------------------

def _quat_to_mat(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) in (w, x, y, z)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def _layout(model_name: str):
    """qpos/qvel addresses: (quat slice, angvel slice, leg qpos slice, leg qvel slice)."""
    if model_name == "pivot":
        return slice(0, 4), slice(0, 3), slice(4, 6), slice(3, 5)
    return slice(3, 7), slice(3, 6), slice(7, 9), slice(6, 8)


def _world_omega(model_name, qpos, qvel):
    qs, ws, _, _ = _layout(model_name)
    R = _quat_to_mat(qpos[..., qs])
    return np.einsum("...ij,...j->...i", R, qvel[..., ws])


def contact_xy_from_states(model_name: str, qpos, qvel, *, radius: float = 0.12,
                           timestep: float = 0.001, xy0=(0.0, 0.0)):
    """Contact point path from a state trajectory (time along axis -2).

    pivot: trapezoidal integration of xdot = r w_y, ydot = -r w_x (world w);
    the first sample is taken to be at ``xy0``. Only states are available
    here, so this is second order: on Gait 1 at timestep 1e-3 it is 3e-4 m
    off after 50 s (MujocoRobot's Hermite update: 3e-6 m).
    plane: the sphere centre's x, y (no integration).
    """
    qpos, qvel = np.asarray(qpos), np.asarray(qvel)
    if model_name == "plane":
        return qpos[..., 0], qpos[..., 1]
    w = _world_omega(model_name, qpos, qvel)
    v = np.stack([radius * w[..., 1], -radius * w[..., 0]], axis=-1)
    inc = 0.5 * timestep * (v[..., 1:, :] + v[..., :-1, :])
    xy = np.concatenate([np.zeros_like(v[..., :1, :]), np.cumsum(inc, axis=-2)], axis=-2)
    xy = xy + np.asarray(xy0, dtype=float)
    return xy[..., 0], xy[..., 1]


def settle_height(m, d, *, depth: float = 1e-4, iters: int = 50) -> float:
    """Lower the plane model's centre to the soft contact's static equilibrium.

    MuJoCo's contact needs a small penetration to carry the weight (~1.2e-6 m
    with the default solref). Starting with the centre at exactly r leaves the
    sphere without normal force for the first few steps, so a leg torque at
    t = 0 makes it slip (up to 0.15 mm on Gait 2). This bisects on the centre
    height for zero vertical acceleration (given the current velocities and
    ctrl) and leaves ``d`` forwarded. Returns the penetration r - z.
    """
    mujoco = _import_mujoco()
    r = float(m.geom_size[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "shell"), 0])
    lo, hi = r - depth, r            # qacc_z > 0 at lo, <= 0 at hi
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        d.qpos[2] = mid
        mujoco.mj_forward(m, d)
        if d.qacc[2] > 0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-15:
            break
    d.qpos[2] = 0.5 * (lo + hi)
    mujoco.mj_forward(m, d)
    return r - d.qpos[2]


# ---------------------------------------------------------------------------
# single robot
# ---------------------------------------------------------------------------

class MujocoRobot:
    """One RRRobot in MuJoCo (``model`` = "pivot" or "plane").

    Keyword arguments go to ``build_mjcf`` (timestep, integrator, kp, kd,
    damping, contact settings, ...). ``hold`` chooses how gait targets are
    sampled over a step (see ``gait_controls``). ``quadrature`` ("hermite" or
    "trapezoid") is how the pivot model's contact point is integrated (see
    ``_step_pivot``). Between steps, change the controls only through
    ``step(ctrl)`` / ``step_gait``: the pivot Hermite update tracks them.

    Attributes: ``model`` (MjModel), ``data`` (MjData), ``name``, ``xml``.
    """

    def __init__(self, model: str = "pivot", *, hold: str = "mid",
                 quadrature: str = "hermite", **kwargs):
        self.mujoco = _import_mujoco()
        self.name = model
        self.kwargs = dict(kwargs)
        self.radius = float(kwargs.get("radius", 0.12))
        self.xml = build_mjcf(model, **kwargs)
        self.model = compile_model(model, **kwargs)
        self.data = self.mujoco.MjData(self.model)
        self.hold = hold
        if quadrature not in ("hermite", "trapezoid"):
            raise ValueError("quadrature must be 'hermite' or 'trapezoid'")
        self.quadrature = quadrature
        self._qs, self._ws, self._ps, self._vs = _layout(model)
        m = self.model
        self._act_dof = m.jnt_dofadr[m.actuator_trnid[:, 0]]
        self._act_gain = m.actuator_gainprm[:, 0] * m.actuator_gear[:, 0]
        self.reset()

    # -- state -----------------------------------------------------------
    @property
    def dt(self) -> float:
        return float(self.model.opt.timestep)

    def reset(self, quat=None, phi=None, omega=None, phidot=None, *, settle: bool = True):
        """Upright at rest at the origin, legs vertical (or the given values).

        ``quat`` (w, x, y, z) body->world; ``omega`` body-frame angular velocity
        (plane: the centre velocity is set to w x (0, 0, r), rolling without
        slip); ``phi``/``phidot`` leg angles and rates.

        Plane model: the centre starts at height r, lowered by ``settle_height``
        to the soft contact's equilibrium (~1.2e-6 m lower) when ``settle``
        (default); ``settle=False`` keeps exactly r, at the price of a slip
        transient in the first milliseconds.
        """
        mj = self.mujoco
        mj.mj_resetData(self.model, self.data)
        d = self.data
        if quat is not None:
            q = np.asarray(quat, dtype=float)
            d.qpos[self._qs] = q / np.linalg.norm(q)
        if phi is not None:
            d.qpos[self._ps] = phi
        if omega is not None:
            d.qvel[self._ws] = omega
            if self.name == "plane":
                # roll without slip from the start: v_centre = w x (0, 0, r)
                w = _quat_to_mat(d.qpos[self._qs]) @ np.asarray(omega, dtype=float)
                d.qvel[0:3] = np.cross(w, [0.0, 0.0, self.radius])
        if phidot is not None:
            d.qvel[self._vs] = phidot
        d.ctrl[:2] = d.qpos[self._ps]
        d.ctrl[2:] = 0.0
        if self.name == "plane" and settle:
            settle_height(self.model, d)
        self._xy = np.zeros(2)
        if self.name == "plane":
            self._xy = d.qpos[0:2].copy()
        mj.mj_forward(self.model, d)
        self._a0 = None                       # contact accel, set lazily
        if self.name == "pivot":
            self._v0, self._a0 = self._contact_rates()
        return self

    def world_omega(self) -> np.ndarray:
        """Angular velocity of the shell in the world frame."""
        return _world_omega(self.name, self.data.qpos, self.data.qvel)

    def quat(self) -> np.ndarray:
        return self.data.qpos[self._qs].copy()

    def phi(self) -> np.ndarray:
        return self.data.qpos[self._ps].copy()

    def contact_xy(self) -> np.ndarray:
        """pivot: integrated contact point; plane: the sphere centre's x, y."""
        if self.name == "plane":
            return self.data.qpos[0:2].copy()
        return self._xy.copy()

    def slip(self) -> np.ndarray:
        """Horizontal slip velocity at the contact, centre velocity - r (w_y, -w_x).

        Zero for ideal rolling (the contact point of a sphere of radius r, centre
        at height r, moves with v_centre + w x (0, 0, -r)). Plane model only.
        """
        if self.name != "plane":
            raise ValueError("slip() is defined for the plane model only")
        w = self.world_omega()
        v = self.data.qvel[0:2]
        return np.array([v[0] - self.radius * w[1], v[1] + self.radius * w[0]])

    def contact_slip(self) -> np.ndarray:
        """Horizontal velocity of the shell's material point at MuJoCo's contact point.

        Unlike ``slip()`` this does not assume the contact lies exactly r below
        the centre, so it excludes the apparent slip ``delta * w`` caused by the
        soft contact's penetration delta. Zero vector when there is no contact.
        """
        if self.name != "plane":
            raise ValueError("contact_slip() is defined for the plane model only")
        d = self.data
        if d.ncon == 0:
            return np.zeros(2)
        w = self.world_omega()
        v = d.qvel[0:3] + np.cross(w, d.contact[0].pos - d.qpos[0:3])
        return v[:2].copy()

    def energy(self) -> float:
        """Total mechanical energy, kinetic + gravitational (mj_energyPos/Vel).

        The zero of potential energy is the world origin (z = 0). Soft-contact
        deformation energy is not included.
        """
        return float(sum(self.energy_parts()))

    def energy_parts(self):
        """(kinetic, potential) of the current state."""
        mj = self.mujoco
        m, d = self.model, self.data
        mj.mj_fwdPosition(m, d)       # kinematics, com, mass matrix
        mj.mj_energyPos(m, d)
        mj.mj_energyVel(m, d)
        return float(d.energy[1]), float(d.energy[0])

    # -- stepping ------------------------------------------------------------
    def _contact_rates(self):
        """(v, a): contact point velocity r (w_y, -w_x) and its time derivative.

        ``a`` uses ``data.qacc``, valid after ``mj_forward`` at the current state
        and ctrl; d/dt (R w_body) = R wdot_body.
        """
        d = self.data
        R = _quat_to_mat(d.qpos[self._qs])
        w = R @ d.qvel[self._ws]
        wd = R @ d.qacc[self._ws]
        r = self.radius
        return np.array([r * w[1], -r * w[0]]), np.array([r * wd[1], -r * wd[0]])

    def _set_ctrl_pivot(self, ctrl):
        """Set ctrl and update the start-of-step contact acceleration (pivot).

        The pivot model has no constraints, so qacc = M^-1 qfrc; a change of
        ctrl changes qacc by M^-1 (gain * gear * dctrl) on the actuated dofs
        (position/velocity actuators are affine in ctrl). This avoids a second
        mj_forward per step.
        """
        d = self.data
        du = np.asarray(ctrl, dtype=float) - d.ctrl
        d.ctrl[:] = ctrl
        if self._a0 is None or not np.any(du):
            return
        dq = np.zeros(self.model.nv)
        np.add.at(dq, self._act_dof, self._act_gain * du)
        x = np.zeros(self.model.nv)
        self.mujoco.mj_solveM(self.model, d, x.reshape(1, -1), dq.reshape(1, -1))
        R = _quat_to_mat(d.qpos[self._qs])
        wd = R @ x[self._ws]
        self._a0 = self._a0 + self.radius * np.array([wd[1], -wd[0]])

    def _step_pivot(self):
        """One mj_step plus a 4th-order (Hermite) update of the contact point.

        x(t+dt) = x + dt/2 (v0 + v1) + dt^2/12 (a0 - a1), with the one-sided
        derivatives a0 (start of step, this step's ctrl) and a1 (end of step,
        same ctrl). The trapezoid alone is second order and, because the held
        ctrl jumps at every step, its error grows with time (~3e-4 m on Gait 1
        after 50 s at dt = 1e-3); the Hermite form is ~3e-6 m. Costs one extra
        mj_forward per step. With ``quadrature="trapezoid"`` it is skipped.
        """
        mj, m, d = self.mujoco, self.model, self.data
        dt = self.dt
        if self.quadrature == "trapezoid":
            v0, _ = self._contact_rates()
            mj.mj_step(m, d)
            v1, _ = self._contact_rates()
            self._xy += 0.5 * dt * (v0 + v1)
            return
        if self._a0 is None:
            mj.mj_forward(m, d)
            _, self._a0 = self._contact_rates()
        v0, a0 = self._v0, self._a0
        mj.mj_step(m, d)
        mj.mj_forward(m, d)           # qacc at the new state, same ctrl
        v1, a1 = self._contact_rates()
        self._xy += 0.5 * dt * (v0 + v1) + dt * dt / 12.0 * (a0 - a1)
        self._v0, self._a0 = v1, a1

    def step(self, ctrl=None, nstep: int = 1):
        """``nstep`` mj_steps with ``ctrl`` held; updates the pivot contact point."""
        if self.name == "pivot":
            if ctrl is not None:
                self._set_ctrl_pivot(ctrl)
            for _ in range(nstep):
                self._step_pivot()
        else:
            if ctrl is not None:
                self.data.ctrl[:] = ctrl
            for _ in range(nstep):
                self.mujoco.mj_step(self.model, self.data)

    def step_gait(self, gait, duration: float, *, record_every: int = 1,
                  controls: Optional[np.ndarray] = None) -> Dict[str, np.ndarray]:
        """Run a Table II gait (1, 2, 3 or a parameter dict) for ``duration`` s.

        The gait clock is the simulation time (``data.time``; 0 after reset).
        Returns a dict of arrays sampled every ``record_every`` steps, the first
        row being the state before the first step:
        ``t`` (n,), ``x``, ``y`` (n,) contact point, ``quat`` (n, 4) (w, x, y, z)
        body->world, ``phi`` (n, 2) leg angles, ``phi_d`` (n, 2) the target held
        over the following step, plus ``slip`` (n, 2) for the plane model.
        ``controls`` (nsteps, 4) overrides the gait.
        """
        mj = self.mujoco
        m, d = self.model, self.data
        dt = self.dt
        n = int(round(duration / dt))
        if controls is None:
            controls = gait_controls(gait, n, dt, t0=d.time, hold=self.hold)
        controls = np.asarray(controls, dtype=float)
        nrec = n // record_every + 1
        out = {k: np.empty(s) for k, s in dict(
            t=(nrec,), x=(nrec,), y=(nrec,), quat=(nrec, 4), phi=(nrec, 2),
            phi_d=(nrec, 2)).items()}
        if self.name == "plane":
            out["slip"] = np.empty((nrec, 2))

        def rec(i, k):
            out["t"][i] = d.time
            out["x"][i], out["y"][i] = self.contact_xy()
            out["quat"][i] = d.qpos[self._qs]
            out["phi"][i] = d.qpos[self._ps]
            out["phi_d"][i] = controls[min(k, n - 1), :2]
            if self.name == "plane":
                out["slip"][i] = self.slip()

        rec(0, 0)
        i = 1
        pivot = self.name == "pivot"
        for k in range(n):
            if pivot:
                self._set_ctrl_pivot(controls[k])
                self._step_pivot()
            else:
                d.ctrl[:] = controls[k]
                mj.mj_step(m, d)
            if (k + 1) % record_every == 0:
                rec(i, k + 1)
                i += 1
        return {k: v[:i] for k, v in out.items()}


# ---------------------------------------------------------------------------
# batched rollouts
# ---------------------------------------------------------------------------

def rollout_batch(model: Union[str, Any], n_envs: int, n_steps: int,
                  controls: Optional[np.ndarray] = None, *,
                  initial_states: Optional[np.ndarray] = None,
                  gait=1, nthread: Optional[int] = None,
                  use_rollout: Optional[bool] = None,
                  return_states: bool = True, **kwargs) -> Dict[str, Any]:
    """Open-loop rollouts of ``n_envs`` robots for ``n_steps`` steps each.

    model
        "pivot", "plane" (compiled with ``compile_model(model, **kwargs)``) or
        an ``MjModel`` built by ``compile_model``.
    controls
        ``(n_envs or 1, n_steps or 1, 4)`` (or ``(n_steps, 4)``) rows
        ``(phi_d1, phi_d2, phid_d1, phid_d2)``, held for one step each; default:
        ``gait`` sampled with ``gait_controls`` (same for every env).
    initial_states
        ``(n_envs or 1, nstate)`` mjSTATE_FULLPHYSICS rows; default: the reset
        state (upright, legs vertical, at rest; plane: lowered to the contact
        equilibrium by ``settle_height``).

    Uses ``mujoco.rollout`` (C++ thread pool, ``nthread`` threads, default the
    CPU count) when available, else a Python loop over ``mj_step``.

    Returns a dict: ``state`` (n_envs, n_steps, nstate) after each step (if
    ``return_states``), ``qpos``/``qvel`` views, ``x``/``y`` contact path
    (n_envs, n_steps + 1) (the first column is the initial state), ``wall``
    seconds, ``steps_per_s`` (env steps per second of wall time, rollout call
    only), ``method`` ("mujoco.rollout" or "python loop"), ``nthread``.
    """
    mujoco = _import_mujoco()
    import os

    if isinstance(model, str):
        name = model
        m = compile_model(model, **kwargs)
    else:
        m = model
        name = "plane" if m.nq == 9 else "pivot"
    dt = float(m.opt.timestep)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(m, spec)

    d0 = mujoco.MjData(m)
    mujoco.mj_resetData(m, d0)
    d0.ctrl[:2] = d0.qpos[-2:]
    if name == "plane":
        settle_height(m, d0)
    if initial_states is None:
        s0 = np.empty(nstate)
        mujoco.mj_getState(m, d0, s0, spec)
        initial_states = s0[None, :]
    initial_states = np.atleast_2d(np.asarray(initial_states, dtype=float))

    if controls is None:
        controls = gait_controls(gait, n_steps, dt)[None]
    controls = np.asarray(controls, dtype=float)
    if controls.ndim == 2:
        controls = controls[None]
    if controls.shape[-1] != m.nu:
        raise ValueError(f"controls must end in {m.nu} columns")

    if nthread is None:
        try:
            nthread = len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            nthread = os.cpu_count() or 1
    try:
        import mujoco.rollout as mjr  # noqa: F401
        have_rollout = True
    except ImportError:
        have_rollout = False
    if use_rollout is None:
        use_rollout = have_rollout
    if use_rollout and not have_rollout:
        raise ImportError("mujoco.rollout is not available in this mujoco")

    init = np.broadcast_to(initial_states, (n_envs, nstate)).copy()
    ctrl = np.broadcast_to(controls, (n_envs, n_steps, m.nu)).copy()

    if use_rollout:
        import mujoco.rollout as mjr
        datas = [mujoco.MjData(m) for _ in range(max(1, nthread))]
        state = np.empty((n_envs, n_steps, nstate))
        with mjr.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
            t0 = _time.perf_counter()
            pool.rollout(m, datas, init, ctrl, nstep=n_steps, state=state)
            wall = _time.perf_counter() - t0
        method = "mujoco.rollout"
    else:
        d = mujoco.MjData(m)
        state = np.empty((n_envs, n_steps, nstate))
        t0 = _time.perf_counter()
        for e in range(n_envs):
            mujoco.mj_setState(m, d, init[e], spec)
            for k in range(n_steps):
                d.ctrl[:] = ctrl[e, k]
                mujoco.mj_step(m, d)
                mujoco.mj_getState(m, d, state[e, k], spec)
        wall = _time.perf_counter() - t0
        method = "python loop"
        nthread = 1

    # FULLPHYSICS = time, qpos, qvel, act, history, plugin (in this order)
    i0 = 1
    qpos = np.concatenate([init[:, None, i0:i0 + m.nq], state[:, :, i0:i0 + m.nq]], axis=1)
    qvel = np.concatenate([init[:, None, i0 + m.nq:i0 + m.nq + m.nv],
                           state[:, :, i0 + m.nq:i0 + m.nq + m.nv]], axis=1)
    radius = float(m.geom_size[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "shell"), 0])
    x, y = contact_xy_from_states(name, qpos, qvel, radius=radius, timestep=dt)
    out = dict(x=x, y=y, wall=wall, steps_per_s=n_envs * n_steps / wall,
               method=method, nthread=nthread, model=name)
    if return_states:
        out.update(state=state, qpos=qpos, qvel=qvel)
    return out
