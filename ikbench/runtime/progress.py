"""Progress of long commands: a bar a person can read, machine-readable lines, or nothing.

A study reports through a :class:`Reporter`: ``advance`` counts units of work (solves, shards,
rounds) towards ``total``, ``say`` tells what is happening now, ``note`` a line that must stay
(a failure). A long unit can say how far it is: ``begin`` marks units as started and
``within(fraction)`` moves the count by that fraction of them (a trajectory's iterations of
the method's cap, its waypoints solved), so the bar and its ETA move during a long
trajectory, not only when it ends. Where it goes is set once per process by
:func:`configure` (the CLI does it from ``--quiet`` and ``--log``):

- ``bar``: a tqdm progress bar on stderr with the count (``6.6/7``: six done, the seventh 60 %
  of its way), rate and ETA, ``say`` as its status; the CLI's choice when stderr is a terminal.
- ``lines``: ``[label] text`` lines on stderr, at most one a second besides the notes; the
  default for library calls (``ikbench.run(..., progress=True)`` in a script).
- ``periodic``: for a log file or a pipe, the CLI's choice when stderr is not a terminal: a
  start line, then a line at most every :data:`PERIODIC_EVERY_S` seconds while the work goes
  on, each with the time since the start, the count and how far the started units are when
  their method says (``[run 0:20] 2/7 done, trajectory 3/7 at 41 %; trajectory 3: iteration
  412, loss 15.2031``), and every note (``[run 0:31] trajectory 4: FAILED: ...``).
- ``off``: nothing (``--quiet``).

With a log stream (``--log FILE``) every event is also one JSON object per line: ``t_s``
(seconds since the reporter started), ``label``, ``event`` (``say``, ``advance``, ``note``,
``close``), ``done`` (units finished), ``total``, ``text``; ``advance`` events at most every
:data:`LOG_EVERY_S` seconds (and always the last one), every other event as it comes
(``within`` is not logged).

Lines come from events, so a long library call or a trajectory whose method says nothing
would leave stderr silent. A **heartbeat** fills such gaps: a daemon thread (one per process,
started with the first enabled reporter, ended when none is left) looks when a line falls
due (and at least every :data:`HEARTBEAT_TICK_S` seconds); when no line went to stderr for
:data:`PERIODIC_EVERY_S` seconds it writes one, in ``lines`` and ``periodic`` modes, for the
reporter that heard the latest event: the periodic line with ``still working``
(``[compare 2:20] 3/7 done, method 4/7 at 40 %; ours-exact: solving; still working``). In
``bar`` mode it redraws a bar not redrawn for that long (its elapsed time and rate move; a
bar not drawn yet stays undrawn). ``off`` and the log get none (the log records events
only). A reporter gets heartbeats while it is enabled and not closed, the command that
opened it has not ended (:func:`reset`), the process is not exiting, and the function that
opened it, or the function of ikbench that called that one, is still running in its thread
(``compare``'s reporter beats while ``run_comparison`` writes; one that a result keeps after
the study returned to a script stays silent). The thread never raises, never touches a
Ctrl-C that a library swallowed (only the events raise it again), and writes under the
events' lock. A library call that holds the GIL all along (a C extension that does not
release it) holds the heartbeat back too.
"""

from __future__ import annotations

import _thread
import atexit
import json
import math
import os
import signal
import sys
import threading
import time
import weakref
from typing import Any, TextIO

MODES = ("bar", "lines", "periodic", "off")
#: Plain lines and logged updates at most this often [s] (notes and the last update always).
LINES_EVERY_S = 1.0
LOG_EVERY_S = 0.5
#: ``periodic`` lines at most this often [s] after the start line (notes always).
PERIODIC_EVERY_S = 10.0
#: The heartbeat looks when a line is due, and besides at least this often [s] (and ten
#: times per :data:`PERIODIC_EVERY_S`): a bar's redraw waits a tick at most.
HEARTBEAT_TICK_S = 1.0
#: What a progress line or a table shows for a method that has no loss (NaN or None).
NO_LOSS = "\u2013"

_config: dict[str, Any] = {"mode": "lines", "log": None, "owned": False}
#: Every line and bar redraw, the events' and the heartbeat's, is written holding this lock.
_lock = threading.RLock()
#: The heartbeat (see the module docstring): its thread, the event that stops it for good
#: (the process exits), the generation (:func:`reset` starts a new one), and when a line
#: last went to stderr (``time.monotonic``; the fake clocks of tests patch ``perf_counter``).
_heartbeat: dict[str, Any] = {"thread": None, "stop": threading.Event(), "generation": 0,
                              "stderr_line": -math.inf}
#: The enabled reporters the heartbeat looks after (a reporter collected leaves it).
_watched: weakref.WeakSet[Reporter] = weakref.WeakSet()
#: Set when a Ctrl-C's KeyboardInterrupt was swallowed by a library (llvmlite's ctypes
#: callbacks, while numba compiles or loads a kernel, and JAX's garbage-collection callback,
#: which any solve that makes garbage can run, print it as "Exception ignored"): the next
#: progress event raises it again, or the main thread a moment later, so the command stops
#: as it was asked to.
_swallowed_ctrl_c = threading.Event()
_swallowed_lock = threading.Lock()
#: How long after a swallowed Ctrl-C the CLI raises it again in the main thread [s] when no
#: progress event came first (``ik`` says a line every 10 s while a library solves).
RERAISE_AFTER_S = 0.05


def ctrl_c_swallowed(reraise_after_s: float | None = None) -> None:
    """Say that a KeyboardInterrupt was swallowed (the CLI's ``sys.unraisablehook``): the next
    progress event raises it again; ``reraise_after_s``: also, if none did by then, it is
    raised in the main thread after that long [s] (as a second SIGINT would be; swallowed
    again, it is raised again)."""
    _swallowed_ctrl_c.set()
    if reraise_after_s is not None:
        timer = threading.Timer(reraise_after_s, _reraise_in_main_thread)
        timer.daemon = True
        timer.start()


def _take_swallowed_ctrl_c() -> bool:
    """True once per swallowed Ctrl-C (whoever raises it again takes it)."""
    if not _swallowed_ctrl_c.is_set():
        return False
    with _swallowed_lock:
        taken = _swallowed_ctrl_c.is_set()
        _swallowed_ctrl_c.clear()
    return taken


def _raise_swallowed_ctrl_c() -> None:
    if _take_swallowed_ctrl_c():
        raise KeyboardInterrupt


def _reraise_in_main_thread() -> None:
    if _take_swallowed_ctrl_c():  # nothing once SIGINT is ignored (the command is ending)
        _thread.interrupt_main(signal.SIGINT)


def configure(mode: str = "lines", log: TextIO | None = None, owned: bool = False) -> None:
    """Where every :class:`Reporter` of this process writes (see the module docstring);
    ``owned``: the log is a file opened for this, closed by :func:`reset`."""
    if mode not in MODES:
        raise ValueError(f"progress mode {mode!r} is not one of {', '.join(MODES)}")
    _config.update(mode=mode, log=log, owned=owned)


def reset() -> None:
    """Back to the library default (``lines``, no log), closing a log file it owns (the CLI
    calls it when a command ends); the reporters opened before it get no more heartbeats."""
    if _config["owned"] and _config["log"] is not None:
        _config["log"].close()
    configure()
    with _lock:
        _heartbeat["generation"] += 1


def mode() -> str:
    """The mode :func:`configure` set (``lines`` unless it was called)."""
    return str(_config["mode"])


class Reporter:
    """One study's progress (see the module docstring).

    Args:
        label: what runs (``compare``, ``bench``), the bar's title and each line's prefix.
        total: units of work in all, if known (else the bar counts without an ETA).
        unit: what a unit is (``solve``, ``shard``).
        enabled: False reports nothing (the studies' ``progress=False``).
        stream: where lines and the bar go (default stderr).
    """

    def __init__(self, label: str, total: int | None = None, unit: str = "it",
                 enabled: bool = True, stream: TextIO | None = None) -> None:
        self.label, self.total, self.unit = label, total, unit
        self.enabled = enabled
        self.stream = stream
        self.completed = 0
        #: Units begun and not yet finished, and how far they are (0 to 1; ``_heard``: a
        #: method said so since they began).
        self.in_flight = 0
        self.fraction = 0.0
        self._heard = False
        self._status: str | None = None
        self._started = time.perf_counter()
        self._last_line = self._last_log = -float("inf")
        self._bar: Any = None
        # the heartbeat's view (time.monotonic): opened, the latest event, the latest line
        # written, the bar's latest redraw by the heartbeat (the bar's clock)
        self._closed = False
        self._opened = self._last_event = time.monotonic()
        self._last_output = self._bar_redrawn = -math.inf
        self._generation = _heartbeat["generation"]
        self._opened_by = _opener(self) if enabled else None
        if enabled:
            _watch(self)

    # ----- what studies call ---------------------------------------------------------------
    def say(self, text: str) -> None:
        """What is happening now (the bar's status; a line at most once a second)."""
        _raise_swallowed_ctrl_c()
        self._last_event = time.monotonic()
        if not self.enabled:
            return
        self._log("say", text)
        self._status = text
        if self._mode() == "bar":
            self._open_bar().set_postfix_str(_one_line(text), refresh=False)
        elif self._mode() == "lines":
            self._line(text, throttle=True)
        elif self._mode() == "periodic":
            self._periodic(text)

    def note(self, text: str) -> None:
        """A line that stays (a failure, a method that is not installed)."""
        _raise_swallowed_ctrl_c()
        self._last_event = time.monotonic()
        if not self.enabled:
            return
        self._log("note", text)
        if self._mode() == "bar":
            from tqdm import tqdm

            with _lock:
                tqdm.write(f"[{self.label}] {_one_line(text)}", file=self._stream())
                self._wrote()
        elif self._mode() == "lines":
            self._line(text)
        elif self._mode() == "periodic":
            self._line(text, clock=True)

    def advance(self, amount: int = 1, text: str | None = None) -> None:
        """``amount`` more units done (begun ones first); ``text``: what was just done."""
        _raise_swallowed_ctrl_c()
        self._last_event = time.monotonic()
        self.completed += amount
        self.in_flight = max(0, self.in_flight - amount)
        if not self.in_flight:
            self.fraction, self._heard = 0.0, False
        if not self.enabled:
            return
        if text:
            self._status = text
        last = self.total is not None and self.completed >= self.total
        self._log("advance", text, throttle=not last)
        if self._mode() == "bar":
            bar = self._open_bar()
            if text:
                bar.set_postfix_str(_one_line(text), refresh=False)
            bar.update(self.position - bar.n)
        elif self._mode() == "lines" and text:
            counted = f"{self.completed}/{self.total}" if self.total else f"{self.completed}"
            self._line(f"{counted} {text}", throttle=not last)
        elif self._mode() == "periodic":
            self._periodic(text)

    def begin(self, amount: int = 1) -> None:
        """``amount`` more units start now (one trajectory, or a batch solved at once); what
        :meth:`within` then says is a fraction of all units begun and not yet finished."""
        self._last_event = time.monotonic()
        if not self.in_flight:
            self.fraction, self._heard = 0.0, False
        self.in_flight += amount

    def within(self, fraction: float) -> None:
        """The units begun are ``fraction`` (0 to 1) of their way: the count moves to
        ``completed + fraction * in_flight`` (never back, never NaN; ignored with no unit
        begun)."""
        _raise_swallowed_ctrl_c()
        if not self.in_flight or not math.isfinite(fraction):
            return
        self._last_event = time.monotonic()
        before = self.position
        self.fraction, self._heard = max(self.fraction, min(fraction, 1.0)), True
        if not self.enabled:
            return
        if self._mode() == "bar" and self.position > before:
            bar = self._open_bar()
            bar.update(self.position - bar.n)
        elif self._mode() == "periodic":
            self._periodic(self._status)

    @property
    def position(self) -> float:
        """Units done, the begun ones counted by their fraction (``6.6``: six done, the
        seventh 60 % of its way)."""
        return self.completed + self.fraction * self.in_flight

    def set_total(self, total: int) -> None:
        """The units of work in all, once known."""
        self.total = total
        if self._bar is not None:
            self._bar.total = total
            self._bar.refresh()

    def close(self) -> None:
        """The study is over: remove the bar (its last state is in the log); no heartbeat
        from here on (events after it still report)."""
        with _lock:
            self._closed = True
            if self._bar is not None:
                self._bar.close()
                self._bar = None
        if self.enabled:
            self._log("close", None)

    def __enter__(self) -> Reporter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----- where it goes -------------------------------------------------------------------
    def _mode(self) -> str:
        return mode() if self.stream is None else "lines"

    def _stream(self) -> TextIO:
        return self.stream or sys.stderr

    def _open_bar(self) -> Any:
        if self._bar is None:
            from tqdm import tqdm

            self._bar = _bar_class(tqdm)(total=self.total, desc=self.label, unit=self.unit,
                                         file=self._stream(), dynamic_ncols=True, leave=False,
                                         mininterval=0.2, miniters=0)  # redraws: by time only
        return self._bar

    def _line(self, text: str, throttle: bool = False, clock: bool = False) -> None:
        now = time.perf_counter()
        if throttle and now - self._last_line < LINES_EVERY_S:
            return
        self._last_line = now
        label = f"{self.label} {_clock(now - self._started)}" if clock else self.label
        self._print(f"[{label}] {_one_line(text) if clock else text}")

    def _periodic(self, text: str | None) -> None:
        """A start line, then at most one line every :data:`PERIODIC_EVERY_S` seconds."""
        now = time.perf_counter()
        if now - self._last_line < PERIODIC_EVERY_S:
            return
        self._last_line = now
        self._print(self._summary(now, text))

    def _summary(self, now: float, text: str | None) -> str:
        """``[run 0:20] 2/7 done, trajectory 3/7 at 41 %; TEXT`` (``now``: perf_counter)."""
        counted = f"{self.completed}/{self.total}" if self.total else f"{self.completed}"
        status = f"; {_one_line(text)}" if text else ""
        return (f"[{self.label} {_clock(now - self._started)}] {counted} done{self._begun()}"
                f"{status}")

    def _print(self, line: str) -> None:
        with _lock:
            print(line, file=self._stream(), flush=True)
            self._wrote()

    def _wrote(self) -> None:
        """A line went out now (the heartbeat waits :data:`PERIODIC_EVERY_S` from it)."""
        self._last_output = time.monotonic()
        if self.stream is None:
            _heartbeat["stderr_line"] = self._last_output

    # ----- the heartbeat (its thread calls these holding _lock) ----------------------------
    def _watching(self) -> bool:
        """Still one to keep a heartbeat for (see the module docstring)?"""
        return (self.enabled and not self._closed
                and self._generation == _heartbeat["generation"]
                and _running(self._opened_by))

    def _quiet_since(self) -> float:
        """When its stream last got a line (or it opened), ``time.monotonic``."""
        since = max(self._opened, self._last_output)
        return max(since, _heartbeat["stderr_line"]) if self.stream is None else since

    def _beat(self) -> None:
        """The heartbeat's line: the periodic line with ``still working`` (it does not hold
        back the next event's line: that one says more)."""
        self._print(f"{self._summary(time.perf_counter(), self._status)}; still working")

    def _redraw(self, period_s: float) -> None:
        """Redraw the bar when it was not drawn for ``period_s`` (its elapsed time moves)."""
        bar = self._bar
        if bar is None:
            return
        now = bar._time()
        if now - max(bar.last_print_t, self._bar_redrawn) >= period_s:
            bar.refresh()
            self._bar_redrawn = now

    def _begun(self) -> str:
        """``, trajectory 7/7 at 60 %`` (units 7-9: ``7-9/9``) once a method said how far the
        begun units are; else nothing."""
        if not (self.in_flight and self._heard):
            return ""
        first, last = self.completed + 1, self.completed + self.in_flight
        which = f"{first}" if first == last else f"{first}-{last}"
        of = f"/{self.total}" if self.total else ""
        return f", {self.unit} {which}{of} at {100.0 * self.fraction:.0f} %"

    def _log(self, event: str, text: str | None, throttle: bool = False) -> None:
        log = _config["log"]
        if log is None:
            return
        now = time.perf_counter()
        if throttle:
            if now - self._last_log < LOG_EVERY_S:
                return
            self._last_log = now
        record = {"t_s": round(now - self._started, 3), "label": self.label, "event": event,
                  "done": self.completed, "total": self.total, "text": text}
        log.write(json.dumps(record) + "\n")
        log.flush()


# ----- the heartbeat ---------------------------------------------------------------------------
#: ikbench's own code (a function here that called the one opening a reporter counts too).
_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep
_Opener = tuple[int, tuple[tuple[int, Any], ...]]


def _opener(reporter: Reporter) -> _Opener | None:
    """(thread, ((frame id, code), ...)) of the function that opened ``reporter`` (its
    constructors skipped) and of its caller when that is ikbench's own (``run_comparison``
    writes what ``compare.run`` solved), or None where the interpreter cannot say."""
    try:
        frame = sys._getframe(1)
        while frame is not None and frame.f_code.co_name == "__init__" \
                and frame.f_locals.get("self") is reporter:
            frame = frame.f_back
    except (AttributeError, ValueError):
        return None
    if frame is None:
        return None
    frames = [frame]
    caller = frame.f_back
    if caller is not None and os.path.abspath(caller.f_code.co_filename).startswith(_PACKAGE):
        frames.append(caller)
    return threading.get_ident(), tuple((id(f), f.f_code) for f in frames)


def _running(opened_by: _Opener | None) -> bool:
    """Is the function that opened a reporter (or its caller in ikbench) still running in its
    thread?"""
    current = getattr(sys, "_current_frames", None)
    if opened_by is None or current is None:
        return True
    ident, frames = opened_by
    frame = current().get(ident)
    while frame is not None:
        if (id(frame), frame.f_code) in frames:
            return True
        frame = frame.f_back
    return False


def _watch(reporter: Reporter) -> None:
    """Look after ``reporter``; start the heartbeat's thread if none runs."""
    with _lock:
        _watched.add(reporter)
        thread = _heartbeat["thread"]
        if _heartbeat["stop"].is_set() or (thread is not None and thread.is_alive()):
            return
        thread = threading.Thread(target=_heartbeat_loop, name="ikbench-progress-heartbeat",
                                  daemon=True)
        try:
            thread.start()
        except RuntimeError:  # the interpreter is shutting down: no heartbeat
            return
        _heartbeat["thread"] = thread


def _heartbeat_loop() -> None:
    """The thread: :func:`_heartbeat_once` when the next line is due, or after a tick at most
    (an event's line moves it on); ends when nothing is left to watch or the process exits.
    Never raises (a stream that fails is the events' business)."""
    stop = _heartbeat["stop"]
    wait_s = 0.0
    while not stop.wait(wait_s):
        wait_s = min(HEARTBEAT_TICK_S, PERIODIC_EVERY_S / 10)
        try:
            with _lock:
                if stop.is_set():
                    return
                due_s = _heartbeat_once()
                if due_s is None:
                    if _heartbeat["thread"] is threading.current_thread():
                        _heartbeat["thread"] = None
                    return
            wait_s = max(0.001, min(wait_s, due_s))
        except Exception:  # a heartbeat must never end the command
            pass


def _heartbeat_once() -> float | None:
    """One look (holding ``_lock``): redraw the bars not drawn for :data:`PERIODIC_EVERY_S`,
    and on each stream silent for that long write one line, for its reporter that heard the
    latest event. Returns the seconds until the next line is due, None when no reporter is
    left to watch."""
    period_s = PERIODIC_EVERY_S
    live = []
    for reporter in list(_watched):
        if reporter._watching():
            live.append(reporter)
        else:
            _watched.discard(reporter)  # closed, from an earlier command, or its study ended
    if not live:
        return None
    due_s = period_s
    for reporter in sorted(live, key=lambda r: r._last_event, reverse=True):
        where = reporter._mode()
        if where == "bar":
            reporter._redraw(period_s)
        elif where in ("lines", "periodic"):
            if time.monotonic() - reporter._quiet_since() >= period_s:
                try:
                    reporter._beat()
                except Exception:  # e.g. its stream was closed: watch it no more
                    _watched.discard(reporter)
                    continue
            due_s = min(due_s, period_s - (time.monotonic() - reporter._quiet_since()))
    return due_s


def _stop_heartbeat() -> None:
    """At exit: stop the heartbeat for good, before the interpreter tears its streams down."""
    _heartbeat["stop"].set()
    thread = _heartbeat["thread"]
    if thread is not None and thread is not threading.current_thread():
        thread.join(timeout=1.0)


def _after_fork_in_child() -> None:
    """A forked child has no heartbeat thread, and its parent's reporters are not its own."""
    global _lock
    _lock = threading.RLock()
    _watched.clear()
    _heartbeat.update(thread=None, stop=threading.Event())


atexit.register(_stop_heartbeat)
if hasattr(os, "register_at_fork"):  # no line half-written across a fork: hold the lock
    os.register_at_fork(before=lambda: _lock.acquire(), after_in_parent=lambda: _lock.release(),
                        after_in_child=_after_fork_in_child)


def message(label: str, text: str, enabled: bool = True) -> None:
    """One line that stays (a stage of a long command), routed as :meth:`Reporter.note`."""
    Reporter(label, enabled=enabled).note(text)


def loss_text(loss: float | None, digits: int = 4) -> str:
    """A loss for a person: ``12.3456``, or :data:`NO_LOSS` for a method without one."""
    value = math.nan if loss is None else float(loss)
    return f"{value:.{digits}f}" if math.isfinite(value) else NO_LOSS


_bar_classes: dict[type, type] = {}


def _bar_class(tqdm: type) -> type:
    """tqdm showing a fractional count rounded (``6.6/7``, not ``6.6000000000000005/7``), a
    whole one as an integer (``6/7``)."""
    if tqdm not in _bar_classes:

        class Bar(tqdm):  # type: ignore[misc, valid-type]
            @property
            def format_dict(self) -> dict[str, Any]:
                values = dict(super().format_dict)
                n = round(float(values["n"]), 2)
                values["n"] = int(n) if n.is_integer() else n
                return values

        _bar_classes[tqdm] = Bar
    return _bar_classes[tqdm]


def _clock(seconds: float) -> str:
    """``m:ss`` (``h:mm:ss`` from an hour on)."""
    minutes, secs = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def _one_line(text: str) -> str:
    return " ".join(str(text).split())
