"""MuJoCo peer model of the RRRobot and its family, for ``benchmarks.vs_mujoco``.

The robot of ``MODEL.md`` (:class:`rrrobot_gym.params.RobotParams`): a massless hemispherical
shell of radius r with five point masses and two massless legs turning about the body Y axis;
and the family it is one member of: a half-ellipsoid shell of semi-axes (a, b, c) along body
x, y, z, the bottom mass Mb at (0, 0, -c), and 1 to 6 legs, leg k a pin mass at its hinge H_k and
a tip mass at H_k + l_k (cos phi_k u_k + sin phi_k v_k) (u_k, v_k orthonormal; the hinge axis is
u_k x v_k). A leg is a dict {"hinge", "u", "v", "length", "mass_pin", "mass_tip"} (m, kg), as
``tests/family_oracle.py`` takes it; without ``shell_axes``/``legs``/``mass_bottom`` every
function here builds the paper's robot, exactly as before the family existed.
``"pivot"``: the shell hangs on a ball joint at its centre, and the contact point is integrated
outside MuJoCo from the rolling kinematics, d/dt (x, y) = the horizontal part of R s' (s the
shell's support point under the centre, body frame; for a sphere xdot = r w_y, ydot = -r w_x).
``"plane"``: a free joint, a sphere (ellipsoid) geom on a plane; MuJoCo's contact is soft, so
rolling without slip is only approximated (see :func:`build_mjcf`).

Conventions (MODEL.md): body frame at the shell's centre, z up when upright; the paper's leg 1
pinned at (0, -r, 0), leg 2 at (0, +r, 0); quaternions (w, x, y, z), body to world. States are
``rrrobot_gym``'s layout, 9 + 2L numbers: contact point (x, y), quaternion, leg angles, body-frame
angular velocity, leg rates. ``mujoco`` is an optional dependency (the project's ``bench`` extra),
imported inside the functions that need it.
"""

from __future__ import annotations

import math
import time as _time
from typing import Callable, NamedTuple, Sequence

import numpy as np

from rrrobot_gym.control import table2_gait
from rrrobot_gym.params import PDGains, RobotParams, check_model


def _import_mujoco():
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("benchmarks.mujoco_peer needs the optional dependency 'mujoco': pip install mujoco "
                          "(or the project's 'bench' extra)") from exc  # fmt: skip
    return mujoco


LEG_KEYS = ("hinge", "u", "v", "length", "mass_pin", "mass_tip")


class FamilyRobot(NamedTuple):
    """One member of the family, as the peer builds it. Make it with :func:`family_robot`."""

    shell_axes: tuple  # m, (a, b, c): the shell's semi-axes along body x, y, z
    legs: tuple  # leg dicts (module docstring), each vector a tuple of 3 floats
    mass_bottom: float  # kg, Mb at (0, 0, -c)

    @property
    def num_legs(self) -> int:
        return len(self.legs)

    @property
    def is_sphere(self) -> bool:
        a, b, c = self.shell_axes
        return a == b == c

    @property
    def state_size(self) -> int:
        return 9 + 2 * self.num_legs


def paper_legs(robot: RobotParams | None = None) -> tuple:
    """The paper's two legs (MODEL.md): pinned at (0, -+r, 0), swinging in the body x-z plane
    (u = x, v = z: phi = 0 along +X, pi/2 straight up; the hinge axis u x v = -Y)."""
    robot = robot or RobotParams()
    r = robot.radius
    return tuple(
        {"hinge": (0.0, y, 0.0), "u": (1.0, 0.0, 0.0), "v": (0.0, 0.0, 1.0), "length": robot.leg_length,
         "mass_pin": robot.mass_pin, "mass_tip": robot.mass_tip}
        for y in (-r, r)
    )  # fmt: skip


def family_robot(shell_axes=None, legs=None, mass_bottom=None) -> FamilyRobot:
    """A checked :class:`FamilyRobot`; each argument left None is the paper's robot's
    (:class:`rrrobot_gym.params.RobotParams`: a sphere of radius r, :func:`paper_legs`, Mb)."""
    robot = RobotParams()
    axes = (robot.radius,) * 3 if shell_axes is None else tuple(float(x) for x in shell_axes)
    if len(axes) != 3 or min(axes) <= 0.0:
        raise ValueError(f"shell_axes must be three positive numbers, got {shell_axes!r}")
    checked = []
    for k, leg in enumerate(paper_legs(robot) if legs is None else legs):
        missing = set(LEG_KEYS) - set(leg)
        if missing:
            raise ValueError(f"leg {k + 1} lacks {sorted(missing)}")
        vectors = {key: tuple(float(x) for x in np.asarray(leg[key], dtype=float).reshape(3)) for key in ("hinge", "u", "v")}
        u, v = np.array(vectors["u"]), np.array(vectors["v"])
        if abs(u @ u - 1.0) > 1e-12 or abs(v @ v - 1.0) > 1e-12 or abs(u @ v) > 1e-12:
            raise ValueError(f"leg {k + 1}'s u and v must be orthonormal, got {u} and {v}")
        checked.append({**vectors, **{key: float(leg[key]) for key in ("length", "mass_pin", "mass_tip")}})
    if not 1 <= len(checked) <= 6:
        raise ValueError(f"the family has 1 to 6 legs, got {len(checked)}")
    return FamilyRobot(axes, tuple(checked), robot.mass_bottom if mass_bottom is None else float(mass_bottom))


def _hinge_axis(leg) -> tuple:
    """u x v: a positive rotation about it turns the leg from u towards v (phi up)."""
    return tuple(float(x) for x in np.cross(leg["u"], leg["v"]))


def build_mjcf(model: str, *, timestep: float = 0.001, friction: float = 10.0, servo: str = "pd",
               shell_axes=None, legs=None, mass_bottom=None, contact_timeconst: float = 0.004) -> str:  # fmt: skip
    """The MJCF XML of a family robot (by default the paper's, with its PD gains), ``model``
    "pivot" or "plane"; ``shell_axes``, ``legs`` and ``mass_bottom`` as :func:`family_robot`.

    Point masses: ``inertiafromgeom="false"``; each is a welded body with an ``<inertial>`` of a
    negligible diaginertia (1e-10 kg m^2 against the robot's ~4e-3). Legs: hinges about u x v
    (the paper's: -Y) at the hinge point, with ``ref = pi/2`` and the leg drawn along v, so qpos of
    a hinge is phi and ``qpos0`` has every leg along v (the paper's: vertical).

    Body damping: the paper's torque k w (k < 0). Joint damping d on a ball joint applies -d times
    the body-frame rate, the same vector as -d w since it is isotropic, so d = -k. MJCF damps all
    six dofs of a free joint alike: :func:`compile_model` zeroes the three translational ones.

    Leg servo: tau = kp (phi_d - phi) + kd (phid_d - phidot) as a ``position`` actuator (kp) and a
    ``velocity`` actuator (kd) per leg; ``ctrl = (phi_d1..phi_dL, phid_d1..phid_dL)``, held over a
    whole ``mj_step`` (so :func:`gait_controls` samples each step's midpoint). The plane model's
    legs are light (effective inertia ~1.2e-4 kg m^2): RK4 at 1e-3 s goes unstable for kd >~ 0.3.
    ``servo="torque"`` instead: a ``motor`` actuator per leg, ``ctrl = (tau_1..tau_L)`` in N m, set
    at every RK4 stage by :meth:`MujocoRobot.run_servo` (any servo law, the motor limits included).

    Plane contact, shell on floor only, tuned for rolling without slip: ``condim=3`` (no torsional
    or rolling friction); ``friction`` far above what the motion needs (the env's floor is 1.0); an
    elliptic cone with ``impratio`` 100 (friction rows much harder than the normal row); NoSlip
    (50 iterations) to remove soft friction's creep; ``solref = (contact_timeconst, 0.3)``, by
    default (0.004, 0.3), stiff and little dissipating (the sphere sinks ~1.2e-6 m; timeconst >=
    2 timestep wants ``timestep`` <= contact_timeconst / 2); solver tolerance 1e-10. With RK4
    MuJoCo re-runs collision and the solvers at every stage. An ellipsoid shell is MuJoCo's
    ``ellipsoid`` geom, whose contact with a plane is its exact support point (checked: the
    contact lies at c + R s); a sphere stays a ``sphere`` geom. A sphere's normal force has no
    moment about its centre, an ellipsoid's has: the soft normal contact's lag then turns the shell,
    and the ellipsoid's error against rigid rolling is about proportional to ``contact_timeconst``
    (docs/notes/family_checks.md).
    """
    check_model(model)
    if servo not in ("pd", "torque"):
        raise ValueError(f"unknown servo {servo!r}: expected 'pd' or 'torque'")
    robot, gains = RobotParams(), PDGains()
    family = family_robot(shell_axes, legs, mass_bottom)
    a, b, c = family.shell_axes
    d = -robot.damping
    pi2 = math.pi / 2
    eps = 1e-10

    def fmt(v):
        return " ".join(repr(float(x)) for x in v)

    def point_mass(name, pos, mass):
        return (f'<body name="{name}" pos="{fmt(pos)}">'
                f'<inertial pos="0 0 0" mass="{float(mass)!r}" '
                f'diaginertia="{eps!r} {eps!r} {eps!r}"/></body>')  # fmt: skip

    if family.is_sphere:
        shape = f'type="sphere" size="{a!r}"'
    else:
        shape = f'type="ellipsoid" size="{fmt((a, b, c))}"'
    # damping d = -k on the root joint; no armature, stiffness or frictionloss
    passive = f'damping="{d!r}" armature="0" frictionloss="0" stiffness="0"'
    if model == "plane":
        root_joint = (
            "<!-- free joint: qpos = (x y z, qw qx qy qz) of the shell centre,\n"
            "           qvel = (world-frame linear velocity, body-frame angular velocity).\n"
            "           MJCF applies this damping to all 6 dofs; compile_model() resets\n"
            "           the 3 translational dof_damping entries to 0 (the damping is\n"
            "           the paper's k*w torque, on the rotation only). -->\n"
            f'      <joint name="root" type="free" {passive}/>'
        )
        shell_pos = (0.0, 0.0, c)
        contact = (f'condim="3" friction="{float(friction)!r} 0 0" '
                   f'solref="{fmt((contact_timeconst, 0.3))}" solimp="{fmt((0.99, 0.999, 0.001, 0.5, 2.0))}" '
                   'contype="1" conaffinity="1"')  # fmt: skip
        shell_geom = f'<geom name="shell" {shape} {contact} rgba="0.8 0.6 0.3 0.5"/>'
        floor = f'<geom name="floor" type="plane" size="0 0 0.05" {contact} rgba="0.5 0.5 0.5 1"/>'
        flags = '<flag energy="enable"/>'
        option_extra = 'impratio="100.0" cone="elliptic" noslip_iterations="50" noslip_tolerance="1e-10"'
    else:
        root_joint = (
            "<!-- ball joint at the shell centre (world origin): qpos = quaternion\n"
            "           body->world, qvel = body-frame angular velocity -->\n"
            f'      <joint name="root" type="ball" pos="0 0 0" {passive}/>'
        )
        shell_pos = (0.0, 0.0, 0.0)
        shell_geom = f'<geom name="shell" {shape} contype="0" conaffinity="0" rgba="0.8 0.6 0.3 0.5"/>'
        floor = ""
        flags = '<flag energy="enable" contact="disable"/>'
        option_extra = ""

    def leg(k, spec):
        # drawn along v (phi = pi/2 = ref); tip point mass at l v in the leg frame
        tip = tuple(spec["length"] * x for x in spec["v"])
        return f"""
      <body name="leg{k}" pos="{fmt(spec["hinge"])}">
        <joint name="phi{k}" type="hinge" axis="{fmt(_hinge_axis(spec))}" pos="0 0 0" ref="{pi2!r}"
               damping="0" armature="0" frictionloss="0" stiffness="0"/>
        <geom name="leg{k}" type="capsule" fromto="0 0 0 {fmt(tip)}" size="0.005"
              contype="0" conaffinity="0" rgba="0.2 0.2 0.8 1"/>
        {point_mass(f"tip{k}", tip, spec["mass_tip"])}
      </body>"""

    numbered = list(enumerate(family.legs, start=1))
    pins = "".join(f"\n      {point_mass(f'pin{k}', spec['hinge'], spec['mass_pin'])}" for k, spec in numbered)
    leg_bodies = "".join(leg(k, spec) for k, spec in numbered)
    if servo == "pd":
        actuators = "\n    <!-- ctrl = (phi_d, phid_d), one per leg each; tau = kp (phi_d - phi) + kd (phid_d - phidot) -->"
        actuators += "".join(f'\n    <position name="pos{k}" joint="phi{k}" kp="{gains.kp!r}"/>' for k, _ in numbered)
        actuators += "".join(f'\n    <velocity name="vel{k}" joint="phi{k}" kv="{gains.kd!r}"/>' for k, _ in numbered)
    else:
        actuators = "\n    <!-- ctrl = leg torques, N m, set at every RK4 stage (MujocoRobot.run_servo) -->"
        actuators += "".join(f'\n    <motor name="tau{k}" joint="phi{k}" gear="1"/>' for k, _ in numbered)
    return f"""<mujoco model="rrrobot_{model}">
  <!-- RRRobot family ({model} model), see benchmarks/mujoco_peer.py:build_mjcf -->
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{float(timestep)!r}" integrator="RK4" gravity="0 0 {-robot.gravity!r}"
          tolerance="1e-10" iterations="100" {option_extra}>
    {flags}
  </option>
  <worldbody>
    {floor}
    <body name="shell" pos="{fmt(shell_pos)}">
      {root_joint}
      {shell_geom}
      {point_mass("bottom", (0, 0, -c), family.mass_bottom)}{pins}{leg_bodies}
    </body>
  </worldbody>
  <actuator>{actuators}
  </actuator>
</mujoco>
"""


def compile_model(model: str, **kwargs):
    """``build_mjcf(model, **kwargs)`` as an ``MjModel``, the plane's free joint damped on its rotation only."""
    mujoco = _import_mujoco()
    m = mujoco.MjModel.from_xml_string(build_mjcf(model, **kwargs))
    if model == "plane":
        adr = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "root")]
        m.dof_damping[adr:adr + 3] = 0.0
    return m


def gait_controls(gait: int, n_steps: int, timestep: float, *, t0: float = 0.0) -> np.ndarray:
    """Controls (n_steps, 4) of Table II gait ``gait`` (the paper's two legs), one row per
    ``mj_step``, sampled at each step's midpoint t0 + (k + 1/2) dt: MuJoCo holds a control over the
    step, and the midpoint makes the held target second-order accurate against a continuous-time servo."""
    g = table2_gait(gait)
    t = (t0 + (np.arange(n_steps) + 0.5) * timestep)[..., None]
    arg = g.frequency * t + np.asarray(g.phase)
    phi, phid = g.amplitude * np.sin(arg) + np.asarray(g.offset), g.amplitude * g.frequency * np.cos(arg)
    return np.concatenate([phi, phid], axis=-1)


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


def support_world(R, body_rate, shell_axes):
    """(R s, d(R s)/dt), world frame: the shell's point under its centre relative to the centre,
    s = -A n / sqrt(n^T A n) (n = R^T z, A = diag(a^2, b^2, c^2)), and its rate for the body-frame
    angular velocity ``body_rate``: w x R s + R s', s' = J (n x Omega), J = ds/dn. A sphere's is
    exactly (0, 0, -r) and still, which keeps the paper's robot's runs to the bit as before."""
    a, b, c = shell_axes
    if a == b == c:
        return np.array([0.0, 0.0, -a]), np.zeros(3)
    axes_sq = np.array([a * a, b * b, c * c])
    n = R[2]
    a_n = axes_sq * n
    sigma = math.sqrt(n @ a_n)
    s = -a_n / sigma
    n_dot = np.cross(n, body_rate)
    s_dot = -axes_sq * n_dot / sigma + a_n * (a_n @ n_dot) / sigma**3
    rs = R @ s
    return rs, np.cross(R @ body_rate, rs) + R @ s_dot


def centre_height(R, shell_axes) -> float:
    """m, the shell centre's height above the ground at attitude R, sqrt(n^T A n) (a sphere: r)."""
    a, b, c = shell_axes
    if a == b == c:
        return a
    n = R[2]
    return math.sqrt(a * a * n[0] ** 2 + b * b * n[1] ** 2 + c * c * n[2] ** 2)


def settle_height(m, d, *, depth: float = 1e-4, iters: int = 50, height: float | None = None) -> float:
    """Lower the plane model's centre to the soft contact's static equilibrium (zero vertical
    acceleration, by bisection) and leave ``d`` forwarded; returns the penetration ``height`` - z
    (``height``: the centre's height without penetration, default the shell's upright height,
    r or c). Starting at exactly that height leaves no normal force for the first steps, so a leg
    torque at t = 0 would make the shell slip."""
    mujoco = _import_mujoco()
    if height is None:
        shell = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "shell")
        size = m.geom_size[shell]
        height = float(size[0] if m.geom_type[shell] == mujoco.mjtGeom.mjGEOM_SPHERE else size[2])
    r = height
    lo, hi = r - depth, r  # qacc_z > 0 at lo, <= 0 at hi
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


class MujocoRobot:
    """One family robot in MuJoCo (the paper's by default). ``shell_axes``, ``legs`` and
    ``mass_bottom`` as :func:`family_robot`; the other keyword arguments go to :func:`build_mjcf`
    (timestep, friction, servo)."""

    def __init__(self, model: str = "pivot", *, shell_axes=None, legs=None, mass_bottom=None, **kwargs):
        self.mujoco = _import_mujoco()
        self.name = model
        self.family = family_robot(shell_axes, legs, mass_bottom)
        self.model = compile_model(model, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, **kwargs)
        self.data = self.mujoco.MjData(self.model)
        L = self.family.num_legs
        if model == "pivot":  # qpos/qvel addresses: quaternion, angular velocity, leg angles, leg rates
            self._qs, self._ws, self._ps, self._vs = slice(0, 4), slice(0, 3), slice(4, 4 + L), slice(3, 3 + L)
        else:
            self._qs, self._ws, self._ps, self._vs = slice(3, 7), slice(3, 6), slice(7, 7 + L), slice(6, 6 + L)
        m = self.model
        self._act_dof = m.jnt_dofadr[m.actuator_trnid[:, 0]]
        self._act_gain = m.actuator_gainprm[:, 0] * m.actuator_gear[:, 0]
        body = self.mujoco.mjtObj.mjOBJ_BODY
        self._tips = [self.mujoco.mj_name2id(m, body, f"tip{k}") for k in range(1, L + 1)]
        self._shell = self.mujoco.mj_name2id(m, body, "shell")
        self.reset()

    @property
    def radius(self) -> float:
        """m, the upright centre's height (the paper's robot: the sphere's radius r)."""
        return self.family.shell_axes[2]

    def reset(self, state=None):
        """Upright at rest at the origin, legs along v (vertical: the paper's start); or ``state``,
        9 + 2L numbers in the module's layout. The plane model's centre is lowered to the soft
        contact's equilibrium (:func:`settle_height`; from ``state``, by the upright start's depth)."""
        mj = self.mujoco
        mj.mj_resetData(self.model, self.data)
        d, L = self.data, self.family.num_legs
        d.ctrl[:] = 0.0
        if self.model.nu == 2 * L:  # the PD actuators: hold the legs where they are
            d.ctrl[:L] = d.qpos[self._ps]
        self._xy = np.zeros(2)
        if state is None:
            if self.name == "plane":
                settle_height(self.model, d)
            mj.mj_forward(self.model, d)
            if self.name == "pivot":
                self._v0, self._a0 = self._contact_rates()
            return self
        state = np.asarray(state, dtype=float)
        if state.shape != (self.family.state_size,):
            raise ValueError(f"a state of {L} legs has {self.family.state_size} numbers, got shape {state.shape}")
        quat = state[2:6] / np.linalg.norm(state[2:6])
        R = _quat_to_mat(quat)
        omega_body = state[6 + L : 9 + L]
        rs, _ = support_world(R, omega_body, self.family.shell_axes)
        d.qpos[self._qs], d.qpos[self._ps] = quat, state[6 : 6 + L]
        d.qvel[self._ws], d.qvel[self._vs] = omega_body, state[9 + L :]
        if self.model.nu == 2 * L:
            d.ctrl[:L] = state[6 : 6 + L]
        if self.name == "plane":
            depth = self._upright_depth()
            d.qpos[0:2] = state[0:2] - rs[:2]
            d.qpos[2] = centre_height(R, self.family.shell_axes) - depth
            d.qvel[0:3] = -np.cross(R @ omega_body, rs)  # rolling: the contact's material point still
        else:
            self._xy = state[0:2] - rs[:2]
        mj.mj_forward(self.model, d)
        if self.name == "pivot":
            self._v0, self._a0 = self._contact_rates()
        return self

    def _upright_depth(self) -> float:
        """m, the plane model's settled penetration upright at rest (a scratch MjData)."""
        d = self.mujoco.MjData(self.model)
        if self.model.nu == 2 * self.family.num_legs:
            d.ctrl[: self.family.num_legs] = d.qpos[self._ps]
        return settle_height(self.model, d)

    def contact_xy(self) -> np.ndarray:
        """The contact point on the ground: the shell centre's x, y plus R s's (plane; for a sphere
        the centre's), or the integrated contact point (pivot)."""
        R = _quat_to_mat(self.data.qpos[self._qs])
        rs, _ = support_world(R, self.data.qvel[self._ws], self.family.shell_axes)
        if self.name == "plane":
            return self.data.qpos[0:2] + rs[:2]
        return self._xy + rs[:2]

    def state(self) -> np.ndarray:
        """The robot's state (9 + 2L,) in rrrobot_gym's layout (:data:`rrrobot_gym.dynamics.STATE_FIELDS`
        for two legs): contact point (:meth:`contact_xy`), quaternion, leg angles, body-frame angular
        velocity (as MuJoCo's ball and free joints give it), leg rates."""
        d = self.data
        return np.concatenate([self.contact_xy(), d.qpos[self._qs], d.qpos[self._ps], d.qvel[self._ws], d.qvel[self._vs]])

    def run_servo(self, torque, duration: float, *, record_every: int | None = None):
        """Advance ``duration`` s (whole steps) with the leg torques ``torque(t, angles, rates)`` ->
        (tau_1..tau_L), N m, t in s since this call, angles and rates tuples of L floats, evaluated at
        every RK4 stage (``servo="torque"``). Returns the lowest leg-tip height above the floor (m)
        and the largest tilt (rad) at any stage; with ``record_every``, also the states (k, 9 + 2L)
        every ``record_every`` steps, the first before the first step."""
        mj, m, d = self.mujoco, self.model, self.data
        L = self.family.num_legs
        if m.nu != L:
            raise ValueError("run_servo needs a model built with servo='torque'")
        n = int(round(duration / float(m.opt.timestep)))
        angle_adr, rate_adr = list(range(self._ps.start, self._ps.stop)), list(range(self._vs.start, self._vs.stop))
        tips, shell, axes, quat_adr = self._tips, self._shell, self.family.shell_axes, self._qs
        t0, q, v, ctrl, xpos, xmat = d.time, d.qpos, d.qvel, d.ctrl, d.xpos, d.xmat  # (views: fetched once)
        seen = [math.inf, 1.0]  # lowest tip above the floor, least cos(tilt)
        sphere = self.family.is_sphere
        floor = -axes[2] if self.name == "pivot" else 0.0  # a sphere pivot's floor is r below its centre
        records = [self.state()] if record_every else None

        def control(m, d):
            ctrl[:L] = torque(d.time - t0, tuple(float(q[i]) for i in angle_adr), tuple(float(v[i]) for i in rate_adr))
            lowest = min(xpos[tip, 2] for tip in tips)
            if self.name == "pivot" and not sphere:  # the floor is sqrt(n^T A n) below the fixed centre
                lowest += centre_height(_quat_to_mat(q[quat_adr]), axes)
            else:
                lowest -= floor
            seen[0] = min(seen[0], lowest)
            seen[1] = min(seen[1], xmat[shell, 8])

        mj.set_mjcb_control(control)
        try:
            if self.name == "pivot":
                mj.mj_forward(m, d)  # the contact's rate under this call's servo
                self._v0, self._a0 = self._contact_rates()
            for k in range(n):
                if self.name == "pivot":
                    self._step_pivot()
                else:
                    mj.mj_step(m, d)
                if record_every and (k + 1) % record_every == 0:
                    records.append(self.state())
        finally:
            mj.set_mjcb_control(None)
        clearance, tilt = seen[0], math.acos(max(-1.0, min(1.0, seen[1])))
        if record_every:
            return clearance, tilt, np.array(records)
        return clearance, tilt

    def _contact_rates(self):
        """(v, a): the rate of the rolling centre's horizontal position (whose contact point is this
        plus R s's, :func:`support_world`), v = -(w x R s), and its rate, from ``data.qacc`` (valid
        after ``mj_forward`` at the current state and ctrl; d/dt (R w_body) = R wdot_body). A
        sphere's: v = r (w_y, -w_x)."""
        d = self.data
        R = _quat_to_mat(d.qpos[self._qs])
        w = R @ d.qvel[self._ws]
        wd = R @ d.qacc[self._ws]
        rs, rs_dot = support_world(R, d.qvel[self._ws], self.family.shell_axes)
        return _neg_horizontal_cross(w, rs), _neg_horizontal_cross(wd, rs) + _neg_horizontal_cross(w, rs_dot)

    def _set_ctrl_pivot(self, ctrl):
        """Set ctrl and update the start-of-step contact acceleration without a second mj_forward:
        the pivot has no constraints and the actuators are affine in ctrl, so a change of ctrl
        changes qacc by M^-1 (gain * gear * dctrl) on the actuated dofs."""
        d = self.data
        du = np.asarray(ctrl, dtype=float) - d.ctrl
        d.ctrl[:] = ctrl
        if not np.any(du):
            return
        dq = np.zeros(self.model.nv)
        np.add.at(dq, self._act_dof, self._act_gain * du)
        x = np.zeros(self.model.nv)
        self.mujoco.mj_solveM(self.model, d, x.reshape(1, -1), dq.reshape(1, -1))
        R = _quat_to_mat(d.qpos[self._qs])
        wd = R @ x[self._ws]
        rs, _ = support_world(R, d.qvel[self._ws], self.family.shell_axes)
        self._a0 = self._a0 + _neg_horizontal_cross(wd, rs)

    def _step_pivot(self):
        """One mj_step and a 4th-order (Hermite) update of the contact point,
        x(t+dt) = x + dt/2 (v0 + v1) + dt^2/12 (a0 - a1), with this step's ctrl at both ends:
        the trapezoid alone errs ~100x more, as the held ctrl jumps at every step."""
        mj, m, d = self.mujoco, self.model, self.data
        dt = float(m.opt.timestep)
        v0, a0 = self._v0, self._a0
        mj.mj_step(m, d)
        mj.mj_forward(m, d)  # qacc at the new state, same ctrl
        v1, a1 = self._contact_rates()
        self._xy += 0.5 * dt * (v0 + v1) + dt * dt / 12.0 * (a0 - a1)
        self._v0, self._a0 = v1, a1

    def step_gait(self, gait, duration: float, *, record_every: int = 1) -> dict:
        """Run Table II gait ``gait`` (two legs) for ``duration`` s from ``data.time``; returns the
        contact point ``x``, ``y`` (n,) every ``record_every`` steps, the first row before the first step."""
        m, d = self.model, self.data
        dt = float(m.opt.timestep)
        n = int(round(duration / dt))
        controls = gait_controls(gait, n, dt, t0=d.time)
        xy = [self.contact_xy()]
        for k in range(n):
            if self.name == "pivot":
                self._set_ctrl_pivot(controls[k])
                self._step_pivot()
            else:
                d.ctrl[:] = controls[k]
                self.mujoco.mj_step(m, d)
            if (k + 1) % record_every == 0:
                xy.append(self.contact_xy())
        xy = np.array(xy)
        return {"x": xy[:, 0], "y": xy[:, 1]}


def _neg_horizontal_cross(p, q) -> np.ndarray:
    """-(p x q)'s x and y, written out so that a sphere's, q = (0, 0, -r), is r (p_y, -p_x) to the bit."""
    return np.array([-(p[1] * q[2] - p[2] * q[1]), -(p[2] * q[0] - p[0] * q[2])])


TorqueLaw = Callable[[float, Sequence[float], Sequence[float]], Sequence[float]]
"""(t s, leg angles (L,), leg rates (L,)) -> the L leg torques, N m."""


def sinusoid_servo(num_legs: int, *, amplitude: float = 0.3, frequency: float = 8.0, offset: float = math.pi / 2,
                   kp: float = 2.0, kd: float = 0.05) -> TorqueLaw:  # fmt: skip
    """A PD servo on the family's test gait: phi_k(t) = offset + amplitude sin(frequency t + beta_k),
    beta_k = 2 pi k / L (k = 1..L), tau = kp (phi_d - phi) + kd (phid_d - phidot) with the gait's
    analytic rate phid_d."""
    phase = 2.0 * math.pi * np.arange(1, num_legs + 1) / num_legs

    def torque(t, angles, rates):
        arg = frequency * t + phase
        target, target_rate = offset + amplitude * np.sin(arg), amplitude * frequency * np.cos(arg)
        return kp * (target - np.asarray(angles)) + kd * (target_rate - np.asarray(rates))

    return torque


def simulate_family(model: str, torque: TorqueLaw, duration: float, *, shell_axes=None, legs=None,
                    mass_bottom=None, timestep: float = 0.0005, sample_dt: float = 0.05, state=None,
                    friction: float = 10.0, contact_timeconst: float = 0.004):  # fmt: skip
    """Run the peer of a family robot (:func:`family_robot`'s arguments; default the paper's) in
    ``model`` for ``duration`` s under the leg torques ``torque`` (a :data:`TorqueLaw`, evaluated
    at every RK4 stage; e.g. :func:`sinusoid_servo`), from ``state`` (9 + 2L numbers; default the
    paper's start: upright at rest at the origin, legs along v) at MuJoCo steps of ``timestep`` s;
    ``friction`` and ``contact_timeconst`` as :func:`build_mjcf` (the plane model's contact).

    Returns (times (T,), states (T, 9 + 2L)) every ``sample_dt`` s (a whole number of steps), in
    the module's layout, and also the lowest leg-tip clearance (m) and largest tilt (rad) seen."""
    robot = MujocoRobot(model, shell_axes=shell_axes, legs=legs, mass_bottom=mass_bottom, timestep=timestep,
                        friction=friction, servo="torque", contact_timeconst=contact_timeconst)  # fmt: skip
    if state is not None:
        robot.reset(state)
    every = int(round(sample_dt / timestep))
    if abs(every * timestep - sample_dt) > 1e-9 * sample_dt:
        raise ValueError(f"sample_dt {sample_dt} is no whole number of steps of {timestep}")
    steps = int(round(duration / timestep))
    clearance, tilt, states = robot.run_servo(torque, steps * timestep, record_every=every)
    return np.arange(len(states)) * every * timestep, states, clearance, tilt


def rollout_batch(m, n_envs: int, n_steps: int, *, gait: int = 1, nthread: int = 1):
    """Wall seconds of ``n_envs`` open-loop rollouts of ``n_steps`` steps of the compiled model
    ``m`` (the paper's robot, PD servo) under ``gait`` from the reset state, and the method:
    ``mujoco.rollout`` (``nthread`` threads) where this mujoco has it, else a Python loop over ``mj_step``."""
    mujoco = _import_mujoco()
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(m, spec)
    d0 = mujoco.MjData(m)
    mujoco.mj_resetData(m, d0)
    d0.ctrl[:2] = d0.qpos[-2:]
    if m.nq == 9:  # the plane model's free joint
        settle_height(m, d0)
    s0 = np.empty(nstate)
    mujoco.mj_getState(m, d0, s0, spec)
    init = np.broadcast_to(s0, (n_envs, nstate)).copy()
    ctrl = np.broadcast_to(gait_controls(gait, n_steps, float(m.opt.timestep)), (n_envs, n_steps, m.nu)).copy()
    state = np.empty((n_envs, n_steps, nstate))
    try:
        import mujoco.rollout as mjr
    except ImportError:
        mjr = None
    if mjr is not None:
        datas = [mujoco.MjData(m) for _ in range(max(1, nthread))]
        with mjr.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
            t0 = _time.perf_counter()
            pool.rollout(m, datas, init, ctrl, nstep=n_steps, state=state)
            return _time.perf_counter() - t0, "mujoco.rollout"
    d = mujoco.MjData(m)
    t0 = _time.perf_counter()
    for e in range(n_envs):
        mujoco.mj_setState(m, d, init[e], spec)
        for k in range(n_steps):
            d.ctrl[:] = ctrl[e, k]
            mujoco.mj_step(m, d)
            mujoco.mj_getState(m, d, state[e, k], spec)
    return _time.perf_counter() - t0, "python loop"
