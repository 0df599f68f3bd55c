"""MuJoCo peer model of the RRRobot, for ``benchmarks.vs_mujoco``.

The robot of ``MODEL.md`` (:class:`rrrobot_gym.params.RobotParams`): a massless hemispherical
shell of radius r with five point masses and two massless legs turning about the body Y axis.
``"pivot"``: the shell hangs on a ball joint at the sphere centre, and the contact point is
integrated outside MuJoCo from xdot = r w_y, ydot = -r w_x (w: world-frame angular velocity).
``"plane"``: a free joint, a sphere geom on a plane; MuJoCo's contact is soft, so rolling without
slip is only approximated (see :func:`build_mjcf`).

Conventions (MODEL.md): body frame at the sphere centre, z up when upright; leg 1 pinned at
(0, -r, 0), leg 2 at (0, +r, 0); quaternions (w, x, y, z), body to world. ``mujoco`` is an
optional dependency (the project's ``bench`` extra), imported inside the functions that need it.
"""

from __future__ import annotations

import math
import time as _time

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


def build_mjcf(model: str, *, timestep: float = 0.001, friction: float = 10.0, servo: str = "pd") -> str:
    """The MJCF XML of the RRRobot (the paper's robot and PD gains), ``model`` "pivot" or "plane".

    Point masses: ``inertiafromgeom="false"``; each is a welded body with an ``<inertial>`` of a
    negligible diaginertia (1e-10 kg m^2 against the robot's ~4e-3). Legs: hinges about -Y with
    ``ref = pi/2``, so qpos of a hinge is phi and ``qpos0`` has both legs vertical.

    Body damping: the paper's torque k w (k < 0). Joint damping d on a ball joint applies -d times
    the body-frame rate, the same vector as -d w since it is isotropic, so d = -k. MJCF damps all
    six dofs of a free joint alike: :func:`compile_model` zeroes the three translational ones.

    Leg servo: tau = kp (phi_d - phi) + kd (phid_d - phidot) as a ``position`` actuator (kp) and a
    ``velocity`` actuator (kd) per leg; ``ctrl = (phi_d1, phi_d2, phid_d1, phid_d2)``, held over a
    whole ``mj_step`` (so :func:`gait_controls` samples each step's midpoint). The plane model's
    legs are light (effective inertia ~1.2e-4 kg m^2): RK4 at 1e-3 s goes unstable for kd >~ 0.3.
    ``servo="torque"`` instead: a ``motor`` actuator per leg, ``ctrl = (tau1, tau2)`` in N m, set at
    every RK4 stage by :meth:`MujocoRobot.run_servo` (any servo law, the motor limits included).

    Plane contact, sphere on floor only, tuned for rolling without slip: ``condim=3`` (no torsional
    or rolling friction); ``friction`` far above what the motion needs (the env's floor is 1.0); an
    elliptic cone with ``impratio`` 100 (friction rows much harder than the normal row); NoSlip
    (50 iterations) to remove soft friction's creep; ``solref = (0.004, 0.3)``, stiff and little
    dissipating (the sphere sinks ~1.2e-6 m; timeconst >= 2 timestep wants ``timestep`` <= 0.002);
    solver tolerance 1e-10. With RK4 MuJoCo re-runs collision and the solvers at every stage.
    """
    check_model(model)
    if servo not in ("pd", "torque"):
        raise ValueError(f"unknown servo {servo!r}: expected 'pd' or 'torque'")
    robot, gains = RobotParams(), PDGains()
    r, l = robot.radius, robot.leg_length
    d = -robot.damping
    pi2 = math.pi / 2
    eps = 1e-10

    def fmt(v):
        return " ".join(repr(float(x)) for x in v)

    def point_mass(name, pos, mass):
        return (f'<body name="{name}" pos="{fmt(pos)}">'
                f'<inertial pos="0 0 0" mass="{float(mass)!r}" '
                f'diaginertia="{eps!r} {eps!r} {eps!r}"/></body>')  # fmt: skip

    # damping d = -k on the root joint; no armature, stiffness or frictionloss
    passive = f'damping="{d!r}" armature="0" frictionloss="0" stiffness="0"'
    if model == "plane":
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
                   f'solref="{fmt((0.004, 0.3))}" solimp="{fmt((0.99, 0.999, 0.001, 0.5, 2.0))}" '
                   'contype="1" conaffinity="1"')  # fmt: skip
        shell_geom = f'<geom name="shell" type="sphere" size="{r!r}" {contact} rgba="0.8 0.6 0.3 0.5"/>'
        floor = f'<geom name="floor" type="plane" size="0 0 0.05" {contact} rgba="0.5 0.5 0.5 1"/>'
        flags = '<flag energy="enable"/>'
        option_extra = 'impratio="100.0" cone="elliptic" noslip_iterations="50" noslip_tolerance="1e-10"'
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
        {point_mass(f"tip{k}", (0, 0, l), robot.mass_tip)}
      </body>"""

    if servo == "pd":
        actuators = f"""
    <!-- ctrl = (phi_d1, phi_d2, phid_d1, phid_d2); tau = kp (phi_d - phi) + kd (phid_d - phidot) -->
    <position name="pos1" joint="phi1" kp="{gains.kp!r}"/>
    <position name="pos2" joint="phi2" kp="{gains.kp!r}"/>
    <velocity name="vel1" joint="phi1" kv="{gains.kd!r}"/>
    <velocity name="vel2" joint="phi2" kv="{gains.kd!r}"/>"""
    else:
        actuators = """
    <!-- ctrl = (tau1, tau2), N m, set at every RK4 stage (MujocoRobot.run_servo) -->
    <motor name="tau1" joint="phi1" gear="1"/>
    <motor name="tau2" joint="phi2" gear="1"/>"""
    return f"""<mujoco model="rrrobot_{model}">
  <!-- RRRobot ({model} model), see benchmarks/mujoco_peer.py:build_mjcf -->
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
      {point_mass("bottom", (0, 0, -r), robot.mass_bottom)}
      {point_mass("pin1", (0, -r, 0), robot.mass_pin)}
      {point_mass("pin2", (0, r, 0), robot.mass_pin)}{leg(1, -1)}{leg(2, +1)}
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
    """Controls (n_steps, 4) of Table II gait ``gait``, one row per ``mj_step``, sampled at each
    step's midpoint t0 + (k + 1/2) dt: MuJoCo holds a control over the step, and the midpoint
    makes the held target second-order accurate against a continuous-time servo."""
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


def settle_height(m, d, *, depth: float = 1e-4, iters: int = 50) -> float:
    """Lower the plane model's centre to the soft contact's static equilibrium (zero vertical
    acceleration, by bisection) and leave ``d`` forwarded; returns the penetration r - z.
    Starting at exactly r leaves no normal force for the first steps, so a leg torque at t = 0
    would make the sphere slip."""
    mujoco = _import_mujoco()
    r = float(m.geom_size[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "shell"), 0])
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
    """One RRRobot in MuJoCo; keyword arguments go to :func:`build_mjcf` (timestep, friction, servo)."""

    def __init__(self, model: str = "pivot", **kwargs):
        self.mujoco = _import_mujoco()
        self.name = model
        self.radius = RobotParams().radius
        self.model = compile_model(model, **kwargs)
        self.data = self.mujoco.MjData(self.model)
        if model == "pivot":  # qpos/qvel addresses: quaternion, angular velocity, leg angles, leg rates
            self._qs, self._ws, self._ps, self._vs = slice(0, 4), slice(0, 3), slice(4, 6), slice(3, 5)
        else:
            self._qs, self._ws, self._ps, self._vs = slice(3, 7), slice(3, 6), slice(7, 9), slice(6, 8)
        m = self.model
        self._act_dof = m.jnt_dofadr[m.actuator_trnid[:, 0]]
        self._act_gain = m.actuator_gainprm[:, 0] * m.actuator_gear[:, 0]
        body = self.mujoco.mjtObj.mjOBJ_BODY
        self._tips = [self.mujoco.mj_name2id(m, body, f"tip{k}") for k in (1, 2)]
        self._shell = self.mujoco.mj_name2id(m, body, "shell")
        self.reset()

    def reset(self):
        """Upright at rest at the origin, legs vertical (the paper's start). The plane model's
        centre is lowered to the soft contact's equilibrium (:func:`settle_height`)."""
        mj = self.mujoco
        mj.mj_resetData(self.model, self.data)
        d = self.data
        d.ctrl[:] = 0.0
        if self.model.nu == 4:  # the PD actuators: hold the legs where they are
            d.ctrl[:2] = d.qpos[self._ps]
        if self.name == "plane":
            settle_height(self.model, d)
        self._xy = np.zeros(2)
        mj.mj_forward(self.model, d)
        if self.name == "pivot":
            self._v0, self._a0 = self._contact_rates()
        return self

    def contact_xy(self) -> np.ndarray:
        """pivot: the integrated contact point; plane: the sphere centre's x, y."""
        if self.name == "plane":
            return self.data.qpos[0:2].copy()
        return self._xy.copy()

    def state(self) -> np.ndarray:
        """The robot's state (13,) in rrrobot_gym's layout (:data:`rrrobot_gym.dynamics.STATE_FIELDS`):
        contact point (:meth:`contact_xy`), quaternion, leg angles, body-frame angular velocity (as
        MuJoCo's ball and free joints give it), leg rates."""
        d = self.data
        return np.concatenate([self.contact_xy(), d.qpos[self._qs], d.qpos[self._ps], d.qvel[self._ws], d.qvel[self._vs]])

    def run_servo(self, torque, duration: float):
        """Advance ``duration`` s (whole steps) with the leg torques ``torque(t, angles, rates)`` ->
        (tau1, tau2), N m, t in s since this call, evaluated at every RK4 stage (``servo="torque"``).
        Returns the lowest leg-tip height above the floor (m) and the largest tilt (rad) at any stage."""
        mj, m, d = self.mujoco, self.model, self.data
        if m.nu != 2:
            raise ValueError("run_servo needs a model built with servo='torque'")
        n = int(round(duration / float(m.opt.timestep)))
        (p1, p2), (v1, v2) = range(self._ps.start, self._ps.stop), range(self._vs.start, self._vs.stop)
        (tip1, tip2), shell = self._tips, self._shell
        t0, q, v, ctrl, xpos, xmat = d.time, d.qpos, d.qvel, d.ctrl, d.xpos, d.xmat  # (views: fetched once)
        seen = [math.inf, 1.0]  # lowest tip, least cos(tilt)

        def control(m, d):
            ctrl[0], ctrl[1] = torque(d.time - t0, (float(q[p1]), float(q[p2])), (float(v[v1]), float(v[v2])))
            seen[0] = min(seen[0], xpos[tip1, 2], xpos[tip2, 2])
            seen[1] = min(seen[1], xmat[shell, 8])

        mj.set_mjcb_control(control)
        try:
            if self.name == "pivot":
                mj.mj_forward(m, d)  # the contact's rate under this call's servo
                self._v0, self._a0 = self._contact_rates()
                for _ in range(n):
                    self._step_pivot()
            else:
                for _ in range(n):
                    mj.mj_step(m, d)
        finally:
            mj.set_mjcb_control(None)
        floor = -self.radius if self.name == "pivot" else 0.0  # the pivot's centre is the origin
        return seen[0] - floor, math.acos(max(-1.0, min(1.0, seen[1])))

    def _contact_rates(self):
        """(v, a): the contact point's velocity r (w_y, -w_x) and its rate, from ``data.qacc``
        (valid after ``mj_forward`` at the current state and ctrl; d/dt (R w_body) = R wdot_body)."""
        d = self.data
        R = _quat_to_mat(d.qpos[self._qs])
        w = R @ d.qvel[self._ws]
        wd = R @ d.qacc[self._ws]
        r = self.radius
        return np.array([r * w[1], -r * w[0]]), np.array([r * wd[1], -r * wd[0]])

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
        self._a0 = self._a0 + self.radius * np.array([wd[1], -wd[0]])

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
        """Run Table II gait ``gait`` for ``duration`` s from ``data.time``; returns the contact
        point ``x``, ``y`` (n,) every ``record_every`` steps, the first row before the first step."""
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


def rollout_batch(m, n_envs: int, n_steps: int, *, gait: int = 1, nthread: int = 1):
    """Wall seconds of ``n_envs`` open-loop rollouts of ``n_steps`` steps of the compiled model
    ``m`` under ``gait`` from the reset state, and the method: ``mujoco.rollout`` (``nthread``
    threads) where this mujoco has it, else a Python loop over ``mj_step``."""
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
