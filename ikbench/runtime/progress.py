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
"""

from __future__ import annotations

import _thread
import json
import math
import signal
import sys
import threading
import time
from typing import Any, TextIO

MODES = ("bar", "lines", "periodic", "off")
#: Plain lines and logged updates at most this often [s] (notes and the last update always).
LINES_EVERY_S = 1.0
LOG_EVERY_S = 0.5
#: ``periodic`` lines at most this often [s] after the start line (notes always).
PERIODIC_EVERY_S = 10.0
#: What a progress line or a table shows for a method that has no loss (NaN or None).
NO_LOSS = "\u2013"

_config: dict[str, Any] = {"mode": "lines", "log": None, "owned": False}
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
    calls it when a command ends)."""
    if _config["owned"] and _config["log"] is not None:
        _config["log"].close()
    configure()


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

    # ----- what studies call ---------------------------------------------------------------
    def say(self, text: str) -> None:
        """What is happening now (the bar's status; a line at most once a second)."""
        _raise_swallowed_ctrl_c()
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
        if not self.enabled:
            return
        self._log("note", text)
        if self._mode() == "bar":
            from tqdm import tqdm

            tqdm.write(f"[{self.label}] {_one_line(text)}", file=self._stream())
        elif self._mode() == "lines":
            self._line(text)
        elif self._mode() == "periodic":
            self._line(text, clock=True)

    def advance(self, amount: int = 1, text: str | None = None) -> None:
        """``amount`` more units done (begun ones first); ``text``: what was just done."""
        _raise_swallowed_ctrl_c()
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
        """The study is over: remove the bar (its last state is in the log)."""
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
        print(f"[{label}] {_one_line(text) if clock else text}", file=self._stream(),
              flush=True)

    def _periodic(self, text: str | None) -> None:
        """A start line, then at most one line every :data:`PERIODIC_EVERY_S` seconds."""
        now = time.perf_counter()
        if now - self._last_line < PERIODIC_EVERY_S:
            return
        self._last_line = now
        counted = f"{self.completed}/{self.total}" if self.total else f"{self.completed}"
        status = f"; {_one_line(text)}" if text else ""
        print(f"[{self.label} {_clock(now - self._started)}] {counted} done{self._begun()}"
              f"{status}", file=self._stream(), flush=True)

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
