"""The explosion watch: a simulation that blows up raises SimulationError, never returns NaN poses.

Explosions (NaN, joint or body speeds beyond physical bounds, bodies through the floor, energy
growing without input, MuJoCo's own instability warnings) raise SimulationError naming the time (on
the motion's clock), the body and the quantity. MuJoCo's warning text is caught per thread, so
simulations on several threads at once give the same results as one after the other; MuJoCo still
prints its own one-line warning to stderr when it resets an unstable state. A hit that would start
a body part faster than a real blow can is refused before the run (ImpactError).
"""

from __future__ import annotations

import math
import sys
import threading
from collections.abc import Callable

import mujoco
import numpy as np

from ..model.errors import ImpactError, SimulationError
from ..model.impact import Impact
from .workspace import Workspace

MAX_JOINT_SPEED = 500.0  # rad/s; muscles reach ~20, a hard hit on a 0.6 kg hand ~150, a numerical blow-up far more


MAX_BODY_SPEED = 30.0  # m/s; a sprinter runs at ~10


FLOOR_TOLERANCE = 0.25  # m a body origin may sink below the floor before it counts as fallen through


# m/s: energy beyond 1/2 M v^2 above the start counts as an explosion. The servos and the root
# assist do work (raising a crouched body to a standing target adds a good part of what half this
# speed allowed, and a reaction during a lunge went over that); a numerical blow-up adds far more,
# and the joint and body speed checks catch it too (docs/measurements.md, "Limits and rules").
ENERGY_ALLOWANCE_SPEED = 10.0


# m/s: the most an impact may set the hit body's centre of mass moving, faster than a batted ball
# (about 45 m/s). Pushes beyond it are refused before simulating: no hit does that to a body part,
# and a little past it the joints spun beyond MAX_JOINT_SPEED (docs/measurements.md, "Limits and
# rules": where, per body part, and what strength reaches it).
MAX_HIT_SPEED = 50.0


_WARNINGS = ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS", "mjWARN_CNSTRFULL", "mjWARN_CONTACTFULL")


_WARNING_IDS = np.array([int(getattr(mujoco.mjtWarning, name)) for name in _WARNINGS], dtype=int)


# MuJoCo's warning handler is one per process; this one hands the text to the run on the calling
# thread (MuJoCo warns from the thread that steps), and to the previous handler, or stderr, otherwise.
_warning_sink = threading.local()


_handler_lock = threading.Lock()


_handler_installed = False


def _install_warning_handler() -> None:
    global _handler_installed
    with _handler_lock:
        if _handler_installed:
            return
        previous: Callable[[str], None] | None = mujoco.get_mju_user_warning()

        def handle(message: str) -> None:
            messages = getattr(_warning_sink, "messages", None)
            if messages is not None:
                messages.append(message)
            elif previous is not None:
                previous(message)
            else:
                sys.stderr.write(f"MuJoCo warning: {message}\n")

        mujoco.set_mju_user_warning(handle)
        _handler_installed = True


class CapturedWarnings:
    """MuJoCo's warning text of this thread's run, caught instead of printed and appended to
    MUJOCO_LOG.TXT in the working folder."""

    def __enter__(self) -> list[str]:
        _install_warning_handler()
        self.messages: list[str] = []
        _warning_sink.messages = self.messages
        return self.messages

    def __exit__(self, *exc: object) -> None:
        _warning_sink.messages = None


class Watch:
    """Explosion detection after each sampled frame; raises SimulationError naming time, body, quantity."""

    def __init__(self, ws: Workspace, data: mujoco.MjData, t0: float, messages: list[str]):
        self.messages = messages
        self.ragdoll = ws.ragdoll
        self.model = ws.model
        self.data = data
        self.t0 = t0
        self.energy_limit: float | None = None
        self.floor = float(data.mocap_pos[0, 2])
        self.body_ids = ws.ragdoll.index.body_ids
        self.dof_body = ws.ragdoll.index.dof_body
        self.warnings = _WARNING_IDS
        self.mass = float(np.sum(ws.model.body_mass))

    def energy(self) -> float:
        """Kinetic + potential energy, computed on demand (cheaper than MuJoCo's per-step flag)."""
        mujoco.mj_energyPos(self.model, self.data)
        mujoco.mj_energyVel(self.model, self.data)
        potential, kinetic = self.data.energy
        return float(potential + kinetic)

    def arm_energy(self) -> None:
        self.energy_limit = self.energy() + 0.5 * self.mass * ENERGY_ALLOWANCE_SPEED**2

    def check(self) -> None:
        """Runs once per sampled frame, so each test is one or two numpy calls on cached indices."""
        d, m = self.data, self.model
        t = self.t0 + d.time
        if d.warning.number[self.warnings].any():
            self._raise_warning(t)
        qpos, qvel = d.qpos, d.qvel
        if not (np.isfinite(qpos).all() and np.isfinite(qvel).all()):
            bad = int(np.argmax(~np.isfinite(qvel))) if not np.isfinite(qvel).all() else 0
            raise SimulationError(
                f"simulation produced NaN at t = {t:.4f} s: body '{self._dof_name(bad)}', quantity qvel"
            )
        hinge = np.abs(qvel[6:])
        fastest = float(hinge.max()) if hinge.size else 0.0
        if fastest > MAX_JOINT_SPEED:
            i = int(np.argmax(hinge)) + 6
            raise SimulationError(
                f"simulation exploded at t = {t:.4f} s: body '{self._dof_name(i)}' joint speed "
                f"{fastest:.1f} rad/s exceeds {MAX_JOINT_SPEED:g}"
            )
        speed = math.hypot(qvel[0], qvel[1], qvel[2])
        if speed > MAX_BODY_SPEED:
            raise SimulationError(
                f"simulation exploded at t = {t:.4f} s: body '{self.ragdoll.root.name}' speed {speed:.1f} m/s "
                f"exceeds {MAX_BODY_SPEED:g}"
            )
        heights = d.xpos[self.body_ids, 2] - self.floor
        if heights.min() < -FLOOR_TOLERANCE:
            b = self.body_ids[int(np.argmin(heights))]
            raise SimulationError(
                f"simulation failed at t = {t:.4f} s: body '{m.body(b).name}' fell through the floor "
                f"(height {heights.min():.2f} m)"
            )
        if self.energy_limit is not None:
            energy = self.energy()
            if energy > self.energy_limit:
                raise SimulationError(
                    f"simulation exploded at t = {t:.4f} s: body '{self.ragdoll.root.name}' (whole ragdoll) energy "
                    f"{energy:.0f} J exceeds {self.energy_limit:.0f} J without input"
                )

    def _raise_warning(self, t: float) -> None:
        """The first of _WARNINGS MuJoCo raised, with its message and the degree of freedom it names."""
        d = self.data
        for name, index in zip(_WARNINGS, _WARNING_IDS, strict=True):
            w = d.warning[int(index)]
            if w.number:
                said = f": {self.messages[-1].split(' The simulation')[0]}" if self.messages else ""
                raise SimulationError(
                    f"simulation unstable at t = {t:.4f} s: MuJoCo warning {name}{said} "
                    f"(degree of freedom {w.lastinfo}, body '{self._dof_name(w.lastinfo)}')"
                )

    def _dof_name(self, dof: int) -> str:
        if 0 <= dof < 6:
            return self.ragdoll.root.name
        return self.dof_body.get(int(dof), "?")


def check_hit_speed(model: mujoco.MjModel, data: mujoco.MjData, body_id: int, impact: Impact) -> None:
    """Refuse an impact that would start the hit body faster than MAX_HIT_SPEED, naming the most
    this bone takes here. The speed is the impulse through the inverse mass matrix at the start
    pose (the whole ragdoll answers, so a hand weighs 1-2 kg, the head 11-18); `data` holds the start
    state after mj_forward, which factored that matrix."""
    jacobian = np.zeros((3, model.nv))
    mujoco.mj_jacBodyCom(model, data, jacobian, None, body_id)
    response = np.zeros((1, model.nv))
    mujoco.mj_solveM(model, data, response, (jacobian.T @ np.asarray(impact.impulse))[None])
    speed = float(np.linalg.norm(jacobian @ response[0]))
    if speed > MAX_HIT_SPEED:
        most = math.floor(impact.strength * MAX_HIT_SPEED / speed)  # rounded down: the figure named passes
        raise ImpactError(
            f"impact on '{impact.bone}' at frame {impact.frame:g}: {impact.strength:g} N·s would start that "
            f"body part at {speed:.1f} m/s; this bone takes at most {most:d} N·s here ({MAX_HIT_SPEED:g} m/s, "
            f"faster than a batted ball). Hit a heavier bone (chest, pelvis) for a harder push.",
            impact,
        )
