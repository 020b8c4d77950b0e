"""What a synthesis run shows while a user waits: its phases, a progress bar, a ticking clock.

:class:`Console` is the run's one voice on stderr:

* :meth:`Console.say` -- one line per phase of the run (``descent-fmus synthesize NAME: ...``);
* :meth:`Console.bar` -- the search's progress (flights when the run has a flight budget, else
  generations; the rate, the front and the problem's headline fields);
* between the two -- a phase with no bar of its own (deriving the input scaling, starting the
  workers, computing the problem's reference, exporting laws) shows how long it has been going,
  so a user never faces a silent terminal.

On a terminal the bar is tqdm's, redrawn every :data:`TICK_SECONDS` even between its updates
(its clock runs while workers start or a long batch flies), and the waiting phases tick in place
(a status line rewritten as often).  Written to a file or a pipe -- a batch job's log -- there are only
plain lines: the progress every :data:`PLAIN_SECONDS` and at the end, a waiting phase's
"still ..." every :data:`PLAIN_SECONDS` (before: tqdm's carriage returns made ~1 800 lines of
one run's log, with the phase lines glued to them).
"""
from __future__ import annotations

import sys
import threading
import time

__all__ = ["Console", "TICK_SECONDS", "PLAIN_SECONDS"]

#: [choice] A waiting phase's clock on a terminal is rewritten this often [s] (progress within a
#: second of any wait).
TICK_SECONDS = 0.5
#: [choice] Off a terminal, a progress line (or a "still ..." line) at most this often [s]: a
#: log of a few hundred lines for a day-long run.
PLAIN_SECONDS = 30.0


class Console:
    """The run's phases, progress bar and waiting clock on ``stream`` (see the module
    docstring); nothing at all when not ``enabled`` (``--quiet``, ``--json``)."""

    def __init__(self, problem_name: str, enabled: bool = True, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self.prefix = f"descent-fmus synthesize {problem_name}"
        self._lock = threading.Lock()
        self._wait: tuple | None = None        # (text, since) of the phase a clock ticks for
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._progress = None
        self._shown = False                    # the clock's status line is on the terminal

    # -- phases -----------------------------------------------------------------------------
    def say(self, text: str) -> None:
        """A phase's line; with no progress bar running, its clock starts."""
        if not self.enabled:
            return
        with self._lock:
            self._clear()
            line = f"{self.prefix}: {text}"
            if self._progress is not None and self.terminal:
                from tqdm import tqdm
                tqdm.write(line, file=self.stream)
            else:
                self.stream.write(line + "\n")
            self.stream.flush()
            self._wait = None if self._progress is not None else (text, time.monotonic())
        if self._wait is not None:
            self._start_clock()

    def _start_clock(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._tick, name="descent-fmus-clock",
                                            daemon=True)
            self._thread.start()

    def _tick(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(TICK_SECONDS):
            with self._lock:
                if self._progress is not None:
                    self._progress.tick()        # the bar's clock runs between its updates
                    continue
                if self._wait is None:
                    continue
                text, since = self._wait
                now = time.monotonic()
                if self.terminal:
                    self.stream.write(f"\r{self.prefix}: {text} ... {now - since:.0f} s\x1b[K")
                    self._shown = True
                elif now - max(since, last) >= PLAIN_SECONDS:
                    self.stream.write(f"{self.prefix}: still {text} ({now - since:.0f} s)\n")
                    last = now
                self.stream.flush()

    def _clear(self) -> None:
        """Erase the clock's status line (terminal), under the lock."""
        if self._shown:
            self.stream.write("\r\x1b[K")
            self._shown = False

    # -- the search's progress ----------------------------------------------------------------
    def bar(self, problem, desc: str, flights_budget: int, generations: int, done: int,
            gen: int):
        """Start the search's progress (the clock stops while it runs); None when disabled."""
        if not self.enabled:
            return None
        with self._lock:
            self._clear()
            self._wait = None
            self._progress = _Progress(self, problem, desc, flights_budget, generations, done,
                                       gen)
        return self._progress

    def end_bar(self) -> None:
        with self._lock:
            if self._progress is not None:
                self._progress.close()
            self._progress = None

    def close(self) -> None:
        """Stop the clock and the bar (the run ended, or was stopped)."""
        self.end_bar()
        self._stop.set()
        with self._lock:
            self._clear()
            self._wait = None
            self.stream.flush()


class _Progress:
    """The search's progress: a tqdm bar on a terminal, else a plain line every
    :data:`PLAIN_SECONDS` and one at the end."""

    def __init__(self, console: Console, problem, desc, flights_budget, generations, done, gen):
        self.console, self.problem = console, problem
        self.flights_budget, self.generations = flights_budget, generations
        self.unit, self.total, initial = (("flight", flights_budget, min(done, flights_budget))
                                          if flights_budget else
                                          ("gen", generations, min(gen, generations)))
        self.desc, self.n, self.post = desc, initial, {}
        self.bar, self._last = None, time.monotonic()
        console._start_clock()
        if console.terminal:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, initial=initial, unit=self.unit, desc=desc,
                            dynamic_ncols=True, file=console.stream)

    def tick(self) -> None:
        """Between updates (the clock's thread, under the console's lock): tqdm's elapsed time
        on a terminal; off it, the plain line when it is due."""
        if self.bar is not None:
            self.bar.refresh()
        elif time.monotonic() - self._last >= PLAIN_SECONDS:
            self._line()

    def update(self, loop, rate: float) -> None:
        with self.console._lock:
            self._update(loop, rate)

    def _update(self, loop, rate: float) -> None:
        m = loop.method
        self.n = (min(loop.flights, self.flights_budget) if self.flights_budget
                  else min(m.generation, self.generations))
        post = dict(m.status(), **{"evals/s": f"{rate:.0f}", "front": len(loop.archive)})
        if len(loop.archive):
            F = loop.archive.F
            for k, n in enumerate(self.problem.objective_names):
                post[f"min {n}"] = f"{F[:, k].min():.4g}"
            post.update(self.problem.report.headline(F))
        self.post = post
        if self.bar is not None:
            self.bar.n = self.n
            self.bar.set_postfix(post, refresh=False)
            self.bar.refresh()
        elif time.monotonic() - self._last >= PLAIN_SECONDS:
            self._line()

    def advance(self, flights: int) -> None:
        """``flights`` more flown inside a batch (between the method's boundaries)."""
        if self.unit != "flight":
            return
        with self.console._lock:
            self._advance(flights)

    def _advance(self, flights: int) -> None:
        self.n = min(self.n + flights, self.total)
        if self.bar is not None:
            self.bar.n = self.n
            self.bar.refresh()
        elif time.monotonic() - self._last >= PLAIN_SECONDS:
            self._line()

    def _line(self) -> None:
        self._last = time.monotonic()
        share = f" ({100 * self.n / self.total:.0f} %)" if self.total else ""
        post = ", ".join(f"{k} {v}" for k, v in self.post.items())
        self.console.stream.write(f"{self.desc}: {self.n}/{self.total} {self.unit}s{share}"
                                  + (f", {post}" if post else "") + "\n")
        self.console.stream.flush()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        else:
            self._line()
