"""The equations of motion of one robot, specialised from the family's one implementation.

:func:`rrrobot_gym.dynamics.derivative_kernel` takes any member of the family: its shell's axes,
its legs' hinges, axes, lengths and masses are numbers it reads at run time. For one robot many
of them are zeros and ones (the paper's legs swing in the body's x-z plane, hinged on its y
axis), and the compiled stepper still multiplies by them: IEEE arithmetic may not fold
``x * 0`` (x could be infinite) or ``x + 0`` (x could be -0), so the compiler keeps them.

:func:`kernel_source` runs the kernel itself on symbols, with the robot's numbers, and writes
out straight-line Python of the operations that remain. It folds only what is exact:
- an operation on two numbers is done while tracing (the same IEEE operation, the same bits);
- ``x * 1``, ``x / 1``, ``x + 0``, ``x - 0`` are x, ``x * -1`` and ``0 - x`` are -x;
- ``x * 0`` and ``0 / x`` are 0 (x is finite wherever the state is);
- an operation already done on the same operands (in either order, for + and *) is reused.

Every other operation stays, in the kernel's own order, so the specialised kernel gives the
general kernel's values on any finite state (bits, up to the sign of a zero). The compiled
stepper takes it for :data:`SPECIALISED` robots (:mod:`rrrobot_gym.compiled`); the numpy
backend and every other robot run the general kernel, and the tests compare the two.
"""

from __future__ import annotations

import functools
import hashlib
import types

import numpy as np

from . import dynamics
from .params import RobotParams, check_model

SPECIALISED = (RobotParams(),)
"""The robots whose compiled stepper runs a specialised kernel: the paper's, the default scene's
(on either model). Each specialised robot compiles a stepper of its own on first use (about as long
as the general one's), so robots made by the hundred (a gait search's, the shape study's, a
randomized batch's) keep the general kernel. docs/benchmarks.md, "The family", has the speed-up."""

_BINARY = {"add": "+", "sub": "-", "mul": "*", "div": "/"}


class _Trace:
    """The operations recorded so far: each (op, operands) once, in the order first done."""

    def __init__(self):
        self.nodes: list = []  # (op, operands): a Value, a float, or an input's (kind, index)
        self.index: dict = {}

    def node(self, op, *operands):
        if op in ("add", "mul") and _key(operands[1]) < _key(operands[0]):
            operands = operands[::-1]  # (IEEE + and * are commutative, bit for bit)
        key = (op, *map(_key, operands))
        if key not in self.index:
            self.index[key] = len(self.nodes)
            self.nodes.append((op, operands))
        return _Value(self, self.index[key])


def _key(operand):
    return (0, operand.at) if isinstance(operand, _Value) else (1, repr(operand))


def _number(x) -> bool:
    return isinstance(x, (float, int, np.floating))


class _Value:
    """A value the kernel computes from the state: arithmetic on it is recorded, with the exact folds."""

    __slots__ = ("at", "trace")
    __array_priority__ = 1000  # (numpy hands np.sqrt and np.maximum of it to __array_ufunc__)

    def __init__(self, trace, at):
        self.trace, self.at = trace, at

    def _op(self, op, a, b):
        return self.trace.node(op, a, b)

    def __add__(self, other):
        return self if _number(other) and other == 0 else self._op("add", self, other)

    def __radd__(self, other):
        return self if _number(other) and other == 0 else self._op("add", other, self)

    def __sub__(self, other):
        return self if _number(other) and other == 0 else self._op("sub", self, other)

    def __rsub__(self, other):
        return -self if _number(other) and other == 0 else self._op("sub", other, self)

    def __mul__(self, other):
        if _number(other) and other in (0, 1, -1):
            return 0.0 if other == 0 else (self if other == 1 else -self)
        return self._op("mul", self, other)

    __rmul__ = __mul__

    def __truediv__(self, other):
        return self if _number(other) and other == 1 else self._op("div", self, other)

    def __rtruediv__(self, other):
        return 0.0 if _number(other) and other == 0 else self._op("div", other, self)

    def __neg__(self):
        op, operands = self.trace.nodes[self.at]
        return operands[0] if op == "neg" else self.trace.node("neg", self)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        if method == "__call__" and ufunc is np.sqrt:
            return self.trace.node("sqrt", *inputs)
        if method == "__call__" and ufunc is np.maximum and inputs[1] == 0.0:
            return self.trace.node("positive_part", inputs[0])
        return NotImplemented

    def __bool__(self):
        raise TypeError("the kernel branched on a value of the state: it cannot be specialised by tracing")


def _sincos(x):
    if _number(x):
        raise TypeError("a leg angle folded to a number: it cannot be specialised by tracing")
    return x.trace.node("sin", x), x.trace.node("cos", x)


@functools.lru_cache(maxsize=8)
def kernel_source(robot: RobotParams, model: str, momentum: bool | None = None) -> str:
    """Python source of ``derivative_kernel(w, at, out, step, k, layout, drive, scratch, kinematic,
    record, momentum)`` for ``robot`` on ``model``: the general kernel's arguments and results (the leg
    torques given, not ``kinematic``; ``momentum`` as this function is given it, whatever the
    kernel is: by default the steppers', on the pivot), its operations on this robot's numbers folded as the
    module docstring says. ``k``, ``layout`` and ``scratch`` are not read: the robot's numbers are
    in the code. Its globals must give ``sincos`` and ``_sqrt`` (as the general kernel's do)."""
    legs, model = robot.num_legs, check_model(model)
    momentum = dynamics.integrates_momentum(model) if momentum is None else bool(momentum)
    size, at, out, drive, scratch, record = dynamics.kernel_work(legs)
    n = 9 + 2 * legs
    trace = _Trace()
    w = [0.0] * size
    for j in range(n):
        w[at + j] = trace.node("in", ("at", j))
    for m in range(legs):
        w[drive + m] = trace.node("in", ("drive", m))
    kernels = {**vars(dynamics), "sincos": _sincos}  # (copies of the kernels whose sincos is the tracer's)
    for fn in dynamics.KERNELS:
        kernels[fn.__name__] = types.FunctionType(fn.__code__, kernels, fn.__name__, fn.__defaults__)
    kernels["derivative_kernel"](w, at, out, 1, dynamics.constants(robot, model), dynamics.leg_layout(robot), drive,
                                 scratch, False, record, momentum)  # fmt: skip
    derivative, rows = w[out : out + n], w[record : record + 2 * legs + 5]
    needed = _needed(trace, derivative)
    lines = ["def derivative_kernel(w, at, out, step, k, layout, drive, scratch, kinematic, record, momentum=False):",
             f'    """The derivative of {robot.num_legs}-leg robot {_digest(robot)} on the {model}{", momentum" if momentum else ""} (rrrobot_gym.specialise)."""']  # fmt: skip
    names: dict = {}
    _write(trace, sorted(needed), names, lines, "    ")
    lines += [f"    w[out + {j} * step] = {_name(v, names)}" for j, v in enumerate(derivative)]
    lines.append("    if record >= 0:")
    _write(trace, sorted(_needed(trace, rows) - needed), names, lines, "        ")
    lines += [f"        w[record + {j} * step] = {_name(v, names)}" for j, v in enumerate(rows)]
    return "\n".join(lines) + "\n"


def operation_count(robot: RobotParams, model: str) -> int:
    """The operations of the specialised kernel's derivative, the record's left out (a leg's
    sincos counts one): what the folding leaves of the general kernel's."""
    derivative = kernel_source(robot, model).split("    if record >= 0:")[0].splitlines()
    return sum(1 for line in derivative if line.startswith("    v") and "= w[" not in line)


def _digest(robot: RobotParams) -> str:
    return hashlib.sha256(repr(robot).encode()).hexdigest()[:12]


def _needed(trace: _Trace, values) -> set:
    """The operations ``values`` depend on."""
    seen, stack = set(), [v.at for v in values if isinstance(v, _Value)]
    while stack:
        at = stack.pop()
        if at not in seen:
            seen.add(at)
            stack.extend(o.at for o in trace.nodes[at][1] if isinstance(o, _Value))
    return seen


def _name(value, names) -> str:
    return names[value.at] if isinstance(value, _Value) else repr(float(value))


def _write(trace: _Trace, order, names, lines, indent):
    """Statements for the operations ``order`` (in the order traced), each into a name of its own."""
    for at in order:
        if at in names:  # (a sine's cosine, written with it)
            continue
        op, operands = trace.nodes[at]
        name = names[at] = f"v{at}"
        if op == "in":
            (kind, j), = operands
            lines.append(f"{indent}{name} = w[{kind} + {j} * step]")
        elif op in ("sin", "cos"):
            other = trace.index[("cos" if op == "sin" else "sin", _key(operands[0]))]
            names[other] = f"v{other}"
            sin, cos = (name, names[other]) if op == "sin" else (names[other], name)
            lines.append(f"{indent}{sin}, {cos} = sincos({_name(operands[0], names)})")
        elif op == "neg":
            lines.append(f"{indent}{name} = -{_name(operands[0], names)}")
        elif op == "sqrt":
            lines.append(f"{indent}{name} = _sqrt({_name(operands[0], names)})")
        elif op == "positive_part":  # (tangential_force's, on a float)
            x = _name(operands[0], names)
            lines.append(f"{indent}{name} = {x} if not {x} < 0.0 else 0.0")
        else:
            a, b = (_name(o, names) for o in operands)
            lines.append(f"{indent}{name} = {a} {_BINARY[op]} {b}")
