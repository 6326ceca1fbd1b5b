"""
What the controller keeps between calls: the one record its parts share (``CoreState``).

``ControllerCore`` is built of parts, each a class made in its constructor with what it needs
(``demand_intake.DemandIntake``, ``jogging.Jogging``, ``motion_ticks.MotionTicks``,
``states_check.StatesCheck``, ``core_settings.CoreSettings``, ``status_report.StatusReport``);
what more than one of them reads or writes lives here, in the one ``CoreState`` each is given,
and nowhere else. Four groups: the state machine (state, level, message, whether the status
changed, when the fault began; ``step`` moves it), the motion (its id, its waypoints, its
profile and timing note, when it settled and arrived), how the latest motion ended and the
latest refused demand (status values), and the settings in force and pending
(``controller_config.DerivedConfig``) with the collision guard. What only jogging keeps is its
own (``jogging.JogSession``); the model of the arm is the core's ``Robot`` (``control.robot``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from mover6_control.control import state_machine as sm
from mover6_control.control.controller_config import ControllerConfig, DerivedConfig
from mover6_control.control.speed_scaling import SpeedScaling


@dataclass(eq=False)
class CoreState:
    """
    The controller's state shared by its parts (module docstring); mutable, one per core.

    The state machine: ``state`` (``state_machine.STATES``), ``level`` ('OK', 'WARN', 'ERROR')
    and ``message`` (the human reason) of the status; ``changed``: the status changed since the
    last tick's output (the node publishes it at once); ``t_fault`` [s]: when the latest fault
    began (None: none yet); only joint states newer than that clear it.

    The motion (the running one, else the latest): ``motion_id`` of the latest accepted demand
    (0 before any); ``waypoints_total`` its waypoints and ``waypoint`` those reached;
    ``motion_profile`` the profile it is timed by; ``timing`` ``timed_plan.plan_demand``'s note
    on it ('' : none); ``t_settle`` [s] when its reference ended (settling began);
    ``arrived_at`` [s] when every joint came inside the goal tolerance (None: not yet).

    How it ended and what was refused, as status values (``status.StatusKey`` keys):
    ``result`` of the latest motion or jog ({} while one runs or before any); ``rejection`` the
    latest refused demand ({} once one is taken).

    The settings: ``derived`` the ``DerivedConfig`` in force (its config, tolerances, velocity
    limits in the driver's units, control period), installed whole by ``CoreSettings``;
    ``pending`` the one waiting for the running motion to end (None: none);
    ``collision_guard`` a callable(plan) that raises on a colliding motion
    (``collision_guard.CollisionGuard``; the node sets it; None: no collision check);
    ``speed_scaling`` the factor motions run at (``speed_scaling.SpeedScaling``, at 1 unless
    given; jogging and stops run at their own speed).
    """

    derived: DerivedConfig
    pending: Optional[DerivedConfig] = None
    state: str = sm.WAITING_FOR_STATES
    level: str = 'WARN'
    message: str = 'waiting for /joint_states'
    changed: bool = True
    t_fault: Optional[float] = None
    motion_id: int = 0
    waypoints_total: int = 0
    waypoint: int = 0
    motion_profile: str = ''
    timing: str = ''
    t_settle: float = 0.0
    arrived_at: Optional[float] = None
    result: dict = field(default_factory=dict)
    rejection: dict = field(default_factory=dict)
    collision_guard: Optional[object] = None
    speed_scaling: Optional[SpeedScaling] = None

    def __post_init__(self) -> None:
        """Scale motions at 1 within the derived acceleration limit unless told otherwise."""
        if self.speed_scaling is None:
            self.speed_scaling = SpeedScaling(len(self.derived.velocity_limits),
                                              self.derived.config.law.a_max)

    @property
    def config(self) -> ControllerConfig:
        """Return the ``ControllerConfig`` in force (``derived``'s)."""
        return self.derived.config

    def step(self, event: str, level: str, message: str) -> None:
        """Step the state machine by ``event``; the status says ``message`` at ``level``."""
        self.state = sm.step(self.state, event)
        self.level, self.message = level, message
        self.changed = True
