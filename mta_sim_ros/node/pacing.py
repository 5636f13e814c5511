"""How a run keeps time: free running against the wall clock, or in lockstep with a controller.
No ROS here.

The session asks the same of both (:class:`Pace`): each firing of the node's tick timer runs the
ticks the pacing allows (:meth:`Pace.fire`), every command received is an answer
(:meth:`Pace.answer`), each tick's published outputs are shown to it (:meth:`Pace.published`), and
/diagnostics carries its figures (:meth:`Pace.measure`, :meth:`Pace.status`).

Free running (:class:`FreeRunning`): a tick is due every ``period`` = tick / target wall seconds
(target = the real-time factor asked for; 0 = as fast as possible, period 0). The timer fires
every ``timer_period`` = the period, but at least every MAX_TIMER_PERIOD seconds, and each firing
runs the ticks due then (:meth:`FreeRunning.due`): the ones whose end the wall clock times the
target has reached, so simulated time never runs ahead of it, up to CATCH_UP of them. A firing
that comes late (a busy executor, a slow tick, the bag writer behind) is made up by the next
ones, at most CATCH_UP - 1 ticks more each, instead of being lost for good (a ROS timer skips the
firings it missed). A tiny target (1e-12) is a timer every MAX_TIMER_PERIOD firing no tick for a
long time, not a period no timer can hold. Two figures say how well it keeps up, both measured on
the injected steady ``clock`` from the latest restart (start, pause, resume, reset, a new target),
so a pause does not count:

* the real-time factor: simulated seconds per wall second over the last ``window`` seconds
  (timing.RealTimeFactor). It is sampled when measured (the 1 Hz diagnostics), not every
  tick: the figure is the same and the tick pays nothing for it;
* the lag: how far simulated time trails the wall clock times the target. Slow ticks make the
  simulation fall behind, they never skip physics. 0 while paused or at target 0.

Lockstep (:class:`Lockstep`; the node's parameter ``lockstep``, fixed at start), for a controller
that answers each output with a command, as Gazebo's lockstep or CARLA's synchronous mode:

1. the first firing runs tick 1 (with the commands held then: the scene's initial ones unless a
   command came before) and publishes its outputs;
2. then the session waits: no tick runs until a command arrives on any command topic
   (steering_angle, speed_setpoint, cmd_vel, ackermann_cmd, implement_lowered; refused or not: it
   is an answer); with ``answer`` topics (the parameter lockstep_answer) until a message has come
   on each of them (a controller setting steering, speed and implement in three messages: each
   sets its own, so the order they come in does not matter);
3. the next firing after an answer runs exactly one tick, holding the latest commands (two
   answers before that firing still make one tick; the node fires at each answer, so one
   message answers one tick);
4. while waiting, every REPUBLISH_EVERY wall seconds the outputs of the last tick are published
   again (not recorded: the bag has them), for a controller that subscribed late or lost them;
5. after ``lockstep_timeout`` wall seconds without an answer it logs once which topics it waits
   on and at which simulation time, and /diagnostics says WARN until the answer comes; it keeps
   waiting (a stalled controller stops the simulation, never steers it by default);
6. pause holds it as in free running; a reset starts the new run at step 1.

The wall clock paces nothing in lockstep (real_time_factor is not used; the real-time factor is
still measured) and the command watchdog is off: a missing answer stops time instead of being
taken for a stale command, so a run is a function of the commands alone and two runs of a
deterministic controller record the same messages at the same log times.
"""
from __future__ import annotations

import math
from typing import Callable, Protocol

from .timing import RealTimeFactor

#: the timer fires at least this often, s (commands are taken and the watchdog looks at each firing)
MAX_TIMER_PERIOD = 0.1
#: most ticks one firing runs: a lag is made up at up to this many times the target
CATCH_UP = 10
#: a tick whose end is due within this fraction of a tick counts as due (rounding)
DUE_SLACK = 1e-6
#: Lockstep: wall seconds between two re-publications of outputs nobody has answered yet.
REPUBLISH_EVERY = 1.0
#: Lockstep: the tick timer's period, s (the first tick, re-publication, the stall warning; the
#: ticks themselves run when an answer arrives).
LOCKSTEP_TIMER_PERIOD = 0.05


class Pace(Protocol):
    """What the session asks of its pacing."""

    period: float  #: wall seconds between two ticks (0: as fast as possible): each tick's deadline
    timer_period: float  #: wall seconds between two firings of the node's tick timer
    paused: bool
    caught_up: int  #: ticks run by a firing after its first, to make up a lag

    def fire(self, sim_time: float, tick: Callable[[], bool]) -> int:
        """One firing of the tick timer, the simulation at ``sim_time``: runs ``tick`` (which
        says whether it ticked) as often as the pacing allows now; returns how many ticked."""

    def answer(self, topic: str = "") -> None:
        """A command arrived on ``topic``."""

    def published(self, outputs: dict[str, bytes], sim_time: float) -> None:
        """A tick published ``outputs`` (topic -> CDR bytes) at ``sim_time``."""

    def restart(self, sim_time: float) -> None:
        """A new run from ``sim_time`` (a reset)."""

    def pause(self, paused: bool, sim_time: float) -> None: ...

    def set_target(self, target: float, sim_time: float) -> None:
        """A new real-time factor asked for."""

    def measure(self, sim_time: float) -> tuple[float, float]:
        """(real-time factor, lag in s) now that the simulation is at ``sim_time``."""

    def status(self, sim_time: float) -> tuple[dict[str, object], list[str]]:
        """What /diagnostics says of the pacing besides ``measure``: values and problems."""

    def describe(self) -> str:
        """The pacing in a few words (the start-up log)."""


class FreeRunning:
    """Ticks paced by the wall clock at ``target`` times real time (the module docstring)."""

    def __init__(self, tick: float, target: float, clock: Callable[[], float], sim_time: float = 0.0,
                 window: float = 5.0):
        self.tick, self.clock, self.window = tick, clock, window
        self.paused = False
        self.caught_up = 0
        self.set_target(target, sim_time)

    def set_target(self, target: float, sim_time: float) -> None:
        """A new real-time factor to keep (its period applies to the timer made from now on)."""
        self.target = target
        self.period = self.tick / target if target > 0 else 0.0
        self.timer_period = min(self.period, MAX_TIMER_PERIOD)
        self.restart(sim_time)

    def due(self, sim_time: float) -> int:
        """How many ticks the firing of now runs, the simulation being at ``sim_time``: 0 while
        paused, 1 at target 0, else the ticks whose end the wall clock has reached since the
        restart (0 to CATCH_UP)."""
        if self.paused:
            return 0
        if self.target <= 0:
            return 1
        behind = ((self.clock() - self.wall_start) * self.target - (sim_time - self.sim_start)) / self.tick
        return math.floor(min(float(CATCH_UP), max(0.0, behind + DUE_SLACK)))

    def fire(self, sim_time: float, tick: Callable[[], bool]) -> int:
        """The ticks due now (one when on time, more to make up a late firing, none while paused)."""
        ran = 0
        for _ in range(self.due(sim_time)):
            if not tick():
                break
            ran += 1
        self.caught_up += max(0, ran - 1)
        return ran

    def answer(self, topic: str = "") -> None:
        """Commands make no ticks: the wall clock does."""

    def published(self, outputs: dict[str, bytes], sim_time: float) -> None:
        """Nothing waits for an answer."""

    def restart(self, sim_time: float) -> None:
        """Measure afresh from now, when the simulation is at ``sim_time``."""
        self.rtf = RealTimeFactor(self.window, clock=self.clock)
        self.rtf.update(sim_time)
        self.wall_start, self.sim_start = self.clock(), sim_time

    def pause(self, paused: bool, sim_time: float) -> None:
        """Paused or running from now; either way the measurement restarts."""
        self.paused = paused
        self.restart(sim_time)

    def measure(self, sim_time: float) -> tuple[float, float]:
        """(real-time factor, lag in s) now that the simulation is at ``sim_time``; the factor is
        0 until wall time has passed since the restart."""
        self.rtf.update(sim_time)
        rtf = self.rtf.value
        lag = 0.0 if self.paused else (self.clock() - self.wall_start) * self.target - (sim_time - self.sim_start)
        return (0.0 if math.isnan(rtf) else rtf), max(0.0, lag)

    def status(self, sim_time: float) -> tuple[dict[str, object], list[str]]:
        return {}, []

    def describe(self) -> str:
        return f"real-time factor {self.target:g}"


class Lockstep:
    """One tick per answer (the module docstring). ``publish`` re-publishes unanswered outputs,
    ``log`` says a stall, ``timeout`` gives the lockstep_timeout parameter (live), ``topics`` are
    the command topics it waits on (their full names, for the log)."""

    timer_period = LOCKSTEP_TIMER_PERIOD
    period = 0.0
    caught_up = 0

    def __init__(self, tick: float, clock: Callable[[], float], publish: Callable[[dict], None], log,
                 timeout: Callable[[], float], topics: list[str], answer: tuple[str, ...] = ()):
        self.clock, self.publish, self.log, self.timeout, self.topics = clock, publish, log, timeout, topics
        self.parts = frozenset(answer)  # the topics one answer is made of (none: any one message)
        self.missing: set[str] = set()
        self.wall = FreeRunning(tick, 0.0, clock)  # paces nothing at target 0; measures the real-time factor
        self.answered = True  # the next firing may tick (the first one does)
        self.published_at = self.republished_at = clock()
        self.last_outputs: dict[str, bytes] = {}
        self.stall_said = False
        self.stalls = 0  # waits that lasted past lockstep_timeout
        self.republications = 0

    @property
    def paused(self) -> bool:
        return self.wall.paused

    def fire(self, sim_time: float, tick: Callable[[], bool]) -> int:
        """One tick if the last outputs were answered, else re-publish them every REPUBLISH_EVERY s
        and say a stall past lockstep_timeout."""
        if self.paused:
            return 0
        if self.answered:
            return int(tick())
        now = self.clock()
        if self.last_outputs and now - self.republished_at >= REPUBLISH_EVERY:
            self.republished_at = now
            self.republications += 1
            self.publish(self.last_outputs)
        if not self.stall_said and self.waiting() > self.timeout():
            self.stall_said = True
            self.stalls += 1
            self.log.warning(self.stall(sim_time))
        return 0

    def answer(self, topic: str = "") -> None:
        """A message on ``topic``: the answer, or with ``parts`` one of them (the answer once each
        has come since the last outputs)."""
        self.missing.discard(topic)
        if not self.missing:
            self.answered = True

    def published(self, outputs: dict[str, bytes], sim_time: float) -> None:
        """From now the tick waits for an answer to these outputs."""
        if self.stall_said:
            self.log.info(f"lockstep: answered; running again at t = {sim_time:.3f} s")
        self.answered, self.stall_said, self.last_outputs = False, False, outputs
        self.missing = set(self.parts)
        self.published_at = self.republished_at = self.clock()

    def restart(self, sim_time: float) -> None:
        """Step 1 again."""
        self.answered, self.stall_said, self.last_outputs = True, False, {}
        self.missing = set()
        self.wall.restart(sim_time)

    def pause(self, paused: bool, sim_time: float) -> None:
        self.wall.pause(paused, sim_time)

    def set_target(self, target: float, sim_time: float) -> None:
        """real_time_factor is not used in lockstep."""

    def measure(self, sim_time: float) -> tuple[float, float]:
        return self.wall.measure(sim_time)

    def waiting(self) -> float:
        """Wall seconds the last outputs have waited for an answer (0 when answered)."""
        return 0.0 if self.answered else self.clock() - self.published_at

    def stall(self, sim_time: float) -> str:
        return (f"lockstep: waiting {self.waiting():.1f} s (wall) for a command on any of "
                f"{', '.join(self.topics)}, answering the outputs at t = {sim_time:.3f} s; still waiting")

    def status(self, sim_time: float) -> tuple[dict[str, object], list[str]]:
        waiting = self.waiting()
        values = {"lockstep_waiting_s": waiting, "lockstep_stalls": self.stalls,
                  "lockstep_republished": self.republications}
        return values, [self.stall(sim_time)] if waiting > self.timeout() else []

    def describe(self) -> str:
        return "lockstep (one tick per answer)"
