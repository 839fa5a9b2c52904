# Copyright 2026 gyro_platform developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""Pacing of the chunked path: reading the next chunk on a helper thread while this one is
simulated (:func:`prefetched`), and chunk sizes that keep a chunk near a wall-time target
(:class:`ChunkPacer`: signals and output commits between chunks)."""
from __future__ import annotations

from typing import Any, Callable, Iterator

from ..physics.jit import abandon_compiles_when


def prefetched(items: Iterator[Any], work: Callable[[Any], Any]) -> Iterator[tuple[Any, Any]]:
    """``(item, work(item))`` for each of ``items`` in order, the next one taken and worked on by
    a reader thread while the caller handles this one: what releases the GIL there (file reads,
    SQLite, the compiled decoder) runs beside the caller's work; at most one item ahead. An
    exception of ``items`` or ``work`` is raised here, after the items before it. Closing the
    generator (``contextlib.closing``; also on an exception in the caller) stops the thread."""
    import queue
    import threading

    q: queue.Queue = queue.Queue(maxsize=1)
    stop = threading.Event()

    def put(entry: tuple) -> bool:
        while not stop.is_set():
            try:
                q.put(entry, timeout=0.05)
                return True
            except queue.Full:
                pass
        return False

    def produce() -> None:
        try:
            with abandon_compiles_when(stop):      # a stop does not wait for a kernel compiling here
                for item in items:
                    if not put((item, work(item), None)):
                        return
        except BaseException as e:                  # raised in the caller, in order
            put((None, None, e))
            return
        put((None, None, StopIteration))

    thread = threading.Thread(target=produce, name="gyro-bag-reader", daemon=True)
    thread.start()
    try:
        while True:
            item, res, err = q.get()
            if err is StopIteration:
                return
            if err is not None:
                raise err
            yield item, res
    finally:
        stop.set()
        thread.join()


class ChunkPacer:
    """Rows in the next chunk, so that a chunk takes about ``target`` s of wall time whatever a
    row costs (signals are taken and outputs committed between chunks; a slow model — full tree,
    micro-steps — must not hold a Ctrl-C or the output for many seconds). Starts at
    ``START_ROWS``, grows at most 4× a chunk, never above ``max_rows`` or below ``START_ROWS``.
    Call it for the size; ``observe(rows, seconds)`` after each chunk. Given the ``total`` rows
    and told each chunk taken (``took(rows)``, where chunks are read), no chunk is above half of
    what is left: the chunks taper at the end, so that the last one, whose writing nothing
    overlaps, is small (a 32768-row last chunk held the replay's end ~12-16 ms). A ``total`` that
    turns out short (a bag's metadata counting fewer rows than it holds) stops the tapering."""

    START_ROWS = 64

    def __init__(self, max_rows: int, target: float = 0.25, total: int | None = None) -> None:
        self.max_rows, self.target = int(max_rows), float(target)
        self.min_rows = self.rows = min(self.START_ROWS, self.max_rows)
        self.total = total
        self.taken = 0

    def __call__(self) -> int:
        if self.total is None or self.taken >= self.total:      # (a count short of the rows: as untold)
            return self.rows
        return min(self.rows, max(self.min_rows, (self.total - self.taken + 1) // 2))

    def took(self, rows: int) -> None:
        """A chunk of ``rows`` rows was taken (the thread that reads the chunks)."""
        self.taken += rows

    def observe(self, rows: int, seconds: float) -> None:
        """The chunk just done had ``rows`` rows and took ``seconds`` s."""
        fit = self.target * rows / seconds if seconds > 0 else float("inf")
        self.rows = int(max(self.min_rows, min(self.max_rows, 4 * self.rows, fit)))
