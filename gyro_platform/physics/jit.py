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

"""How the numba kernels are compiled and cached (imports numba and ``errors`` only).

Every kernel module takes ``njit`` from here, so that importing any of them installs
:class:`PackageCacheLocator` first: the package's kernels are cached under
``$NUMBA_CACHE_DIR/gyro_platform`` if that is set, else ``$XDG_CACHE_HOME/gyro_platform/numba``
(``~/.cache/…``), in a folder named by a digest of the package's kernel sources (the ``.py``
files that take ``njit`` from here, and the package modules they import from: numba freezes
imported constants into the kernels) and the numba version. A fresh clone, a reinstall, a colcon
workspace or a container sharing that folder reuses what any of them compiled from the same
sources; a change to any kernel file gives a new folder (numba's own in-tree cache misses a
change in a callee's file). ``GYRO_PLATFORM_IN_TREE_CACHE=1`` restores numba's in-tree cache.
Processes compiling at once (``gyro-platform compile``'s parallel parts, Dask workers) add
their kernels to a cache index under an exclusive lock (:func:`_locked_save`): numba's own
save reads, extends and rewrites the index unlocked, so two processes adding different
signatures of one kernel could both take data file ``.1.nbc`` and leave an index entry naming
the other's machine code. A cached kernel loads without numba's refresh of its
implementation registries (:func:`_load_without_refresh`: ~0.25 s of every process's start),
and without initialising numba's installed extensions, which a compile does first
(:func:`_chain_init`: reading every installed distribution's entry points, ~8–14 ms).
While a kernel compiles, the garbage collector runs less often (:func:`_sparse_gc_compile`,
``COMPILE_GC_THRESHOLD``: numba makes millions of short-lived objects, and the default
thresholds spent ~7 % of a compile walking them). At a process's first compile,
:mod:`.lean_overloads` makes numba's library pieces that cost more than their kernels cheaper
(a slice assignment's shape-mismatch message).

:func:`compile_notices` (command-line processes, Dask workers, the rclpy node): while kernels
compile, one line on stderr, then one line per compiled kernel; and a compile asked for on the
main thread runs on a helper thread while the main thread waits, so that SIGINT/SIGTERM
(``errors.StopSignals``) stop the command at once instead of after the compile (LLVM runs for
seconds without returning to the interpreter); :func:`abandon_compiles_when` does the same for
a worker thread (the replay's bag reader) whose consumer stops, and inside
:func:`compiles_refused` a kernel that would compile raises :class:`CompileRefused` from its
compile event, before any typing (the node tells a cold cache so: ``engine.remote``). :func:`cache_dir` is the folder
in use. :func:`cached_array` keeps a constant array the kernels computed (the linear model's rest
matrices) in that folder beside them, so that a later process loads no kernel to get it.
:func:`cache_files` reads that folder as files and :func:`add_cache_files` installs them in
another machine's (a new Dask worker host: ``sweep.kernels``), adding only what it lacks.
"""
from __future__ import annotations

from contextlib import contextmanager
import gc
import hashlib
import itertools
import os
from pathlib import Path
import re
import sys
import threading
import time
from typing import Callable

import numba
from numba import njit  # noqa: F401  (re-exported: the kernel modules' decorator)
from numba.core import caching, config, entrypoints, event
from numba.core.dispatcher import Dispatcher
from numba.core.runtime import rtsys
import numpy as np

from . import kernel_loading, lean_overloads
from ..signals import StopSignals

__all__ = ["njit", "plain", "cache_dir", "cached_array", "cache_files", "add_cache_files", "compile_notices",
           "quiet_compile_header", "when_compiling",
           "not_when_compiling", "compiled_elsewhere", "notices_prog", "abandon_compiles_when", "CompileAbandoned",
           "compiles_refused", "CompileRefused", "can_refuse_compiles",
           "PackageCacheLocator", "source_digest", "digest_sources"]

#: the package folder (the kernel sources below it get the locator)
PACKAGE = Path(__file__).resolve().parents[1]


#: ``from X import names`` (names on one line or in parentheses over several)
_FROM_IMPORT = re.compile(rb"^[ \t]*from[ \t]+(\.*)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)", re.M)


def _package_imports(path: str, data: bytes, files: frozenset[str]) -> set[str]:
    """The package's own modules (of ``files``, absolute paths) that the module at ``path``
    (source ``data``) imports from (``from .x import y``, ``from . import y``, ``from
    gyro_platform.x import y``). Strings, not ``Path``: this runs at every process's start."""
    found: set[str] = set()
    for m in _FROM_IMPORT.finditer(data):
        dots, module = len(m.group(1)), m.group(2).decode()
        if dots:
            base = path
            for _ in range(dots):
                base = os.path.dirname(base)
        elif module.split(".")[0] == PACKAGE.name:
            base = str(PACKAGE.parent)
        else:
            continue
        stem = os.path.join(base, *module.split(".")) if module else base
        names = [n.split()[0] for n in m.group(3).decode().strip("()").replace("\n", " ").split(",")
                 if n.split() and not n.split()[0].startswith("#")]
        for cand in [stem] + [os.path.join(stem, n) for n in names]:     # a module, or modules named in it
            for f in (cand + ".py", os.path.join(cand, "__init__.py")):
                if f in files:
                    found.add(f)
    return found


def digest_sources() -> list[Path]:
    """The files whose bytes name the cache folder: the kernel modules (taking ``njit`` from
    here) and every package module they import from, transitively. numba freezes a kernel's
    globals when it compiles, constants imported from other modules (the step controller's
    ``COARSEN``, ``SWITCH_MIN`` …) included, so a change there must give a new folder too. This
    module and what it imports (how kernels are compiled, cached and loaded, not what they
    compute) are left out."""
    source = {}
    for folder, dirs, names in os.walk(PACKAGE):        # PACKAGE is resolved: no resolve per file
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for name in names:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                with open(path, "rb") as f:
                    source[path] = f.read()
    files = frozenset(source)           # membership, not a stat per candidate
    here = str(Path(__file__).resolve())      # resolved as PACKAGE is: spelled as the keys of ``source``
    todo = [p for p, data in source.items() if p != here and b"jit import njit" in data]
    seen: set[str] = set()
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        if p != here:
            todo.extend(_package_imports(p, source[p], files) - seen)
    seen.discard(here)
    return sorted(map(Path, seen))


def source_digest() -> str:
    """Digest (16 hex) of :func:`digest_sources` (read as bytes) and of the numba version: the
    cache folder's name."""
    global _DIGEST
    if _DIGEST is None:
        h = hashlib.sha256(numba.__version__.encode())
        for p in digest_sources():
            h.update(str(p.relative_to(PACKAGE.resolve())).encode())
            h.update(p.read_bytes())
        _DIGEST = h.hexdigest()[:16]
    return _DIGEST


_DIGEST: str | None = None


def cache_dir() -> Path:
    """The folder the package's compiled kernels are cached in (see module doc)."""
    if config.CACHE_DIR:
        base = Path(config.CACHE_DIR) / "gyro_platform"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "gyro_platform" / "numba"
    return base / source_digest()


def plain(kernel: Callable) -> Callable:
    """The Python function of a kernel (its ``py_func``: run by the interpreter, nothing to
    compile, for a few calls at set-up); the kernel itself under ``NUMBA_DISABLE_JIT=1``."""
    return getattr(kernel, "py_func", kernel)


def cached_array(name: str, key: str, shape: tuple[int, ...], compute: Callable[[], np.ndarray]) -> np.ndarray:
    """``compute()`` (float64, ``shape``), kept in :func:`cache_dir`/constants as
    ``<name>-<digest of key>.npy``: the folder's name is the digest of the kernels' code, ``key``
    names the inputs exactly (e.g. the parameters' float64 bytes). A process that finds the file reads it
    (~0.2 ms) instead of loading the kernels that compute it. A missing, damaged or foreign file
    is computed again and rewritten (whole: written aside, then renamed); a folder that cannot be
    written keeps nothing."""
    path = cache_dir() / "constants" / f"{name}-{hashlib.sha256(key.encode()).hexdigest()[:20]}.npy"
    try:
        a = np.load(path, allow_pickle=False)
        if a.shape == shape and a.dtype == np.float64 and np.isfinite(a).all():
            return a
    except (OSError, ValueError, EOFError):
        pass
    a = np.ascontiguousarray(compute(), dtype=np.float64)
    _write_whole(path, lambda f: np.save(f, a, allow_pickle=False))
    return a


def _write_whole(path: Path, write: Callable) -> bool:
    """``write(file)`` into a temporary beside ``path``, then renamed to it: a reader finds the
    whole file or none. False (nothing left behind) when the folder cannot be written."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as f:
            write(f)
        os.replace(tmp, path)
        return True
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass
        return False


def cache_files(base: Path | None = None) -> dict[str, bytes]:
    """The kernel cache folder ``base`` (default :func:`cache_dir`) as files: path relative to
    it (POSIX) → bytes, the lock files and temporaries left out. :func:`add_cache_files` installs
    them in another machine's folder of the same code version (``sweep.kernels``)."""
    base = cache_dir() if base is None else base
    files: dict[str, bytes] = {}
    for p in sorted(base.rglob("*")):
        if p.suffix in (".lock", ".tmp") or not p.is_file():
            continue
        try:
            files[p.relative_to(base).as_posix()] = p.read_bytes()
        except OSError:                     # removed meanwhile: not shipped
            pass
    return files


def _kernel_of(rel: str) -> str:
    """The kernel a cache file belongs to: numba's index ``<kernel>.nbi`` and its data files
    ``<kernel>.<n>.nbc`` → ``<kernel>``; any other file (a constant) is its own."""
    if rel.endswith(".nbi"):
        return rel[:-4]
    if rel.endswith(".nbc"):
        return rel.rsplit(".", 2)[0]
    return rel


def add_cache_files(files: dict[str, bytes], base: Path | None = None) -> int:
    """Install in the kernel cache folder ``base`` (default :func:`cache_dir`) the kernels and
    constants of ``files`` (:func:`cache_files` of a folder of the same code version) that it
    does not hold; returns how many were added. A kernel whose index is there stays as it is
    (its data file names are that index's); otherwise its data files are written first and its
    index last, each whole, under the index's lock (a process loading it meanwhile finds an entry
    only once its data is there; one compiling it meanwhile adds its entry after). numba loads
    an entry only for the CPU it was compiled for (the index keys by the target's name and
    features): on another CPU the kernel compiles as before. Paths that leave ``base`` are
    refused (ValueError) before anything is written."""
    base = cache_dir() if base is None else base
    groups: dict[str, list[str]] = {}
    for rel in files:
        parts = rel.split("/")
        if rel.startswith("/") or any(x in ("", ".", "..") for x in parts):
            raise ValueError(f"kernel cache file {rel!r} is not a path inside the cache folder")
        groups.setdefault(_kernel_of(rel), []).append(rel)
    added = 0
    for kernel, rels in sorted(groups.items()):
        index = base / (kernel + ".nbi")
        if not any(r.endswith(".nbi") for r in rels):       # a constant
            if not (base / kernel).exists() and _write_whole(base / kernel, lambda f: f.write(files[kernel])):
                added += 1
            continue
        if index.exists():
            continue
        index.parent.mkdir(parents=True, exist_ok=True)
        with _index_lock(str(index)):
            if index.exists():                              # saved by a compile meanwhile
                continue
            ok = all(_write_whole(base / r, lambda f, r=r: f.write(files[r]))
                     for r in sorted(rels, key=lambda r: r.endswith(".nbi")))
            added += ok
    return added


class PackageCacheLocator(caching._CacheLocator):
    """numba cache locator of the package's kernels: :func:`cache_dir`/<module folder>; the
    source stamp is the digest of the package's kernel sources (not the file's path or mtime)."""

    #: (module file, cache folder) → the module's cache folder (str), or None when the file is not
    #: the package's or its folder cannot be written: decided once per module, not per kernel
    #: (~100 at a process's start)
    _folders: dict[tuple[str, Path], str | None] = {}

    def __init__(self, py_func, py_file, cache_path: str):
        self._lineno = py_func.__code__.co_firstlineno
        self._py_file = py_file             # numba's warning about an uncachable function names it
        self._cache_path = cache_path

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return source_digest()

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def _folder(cls, py_func, py_file: str, base: Path) -> str | None:
        try:
            rel = Path(py_file).resolve().relative_to(PACKAGE)
        except ValueError:
            return None                     # not one of ours: numba's own locators
        path = str(base / rel.parent)
        try:
            cls(py_func, py_file, path).ensure_cache_path()     # numba's: made, and writable
        except OSError:
            return None                     # not writable: numba's own locators
        return path

    @classmethod
    def from_function(cls, py_func, py_file):
        if os.environ.get("GYRO_PLATFORM_IN_TREE_CACHE") == "1":
            return None
        key = (py_file, cache_dir())
        path = cls._folders.get(key, False)
        if path is False:
            path = cls._folders[key] = cls._folder(py_func, *key)
        return None if path is None else cls(py_func, py_file, path)


if PackageCacheLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, PackageCacheLocator)


@contextmanager
def _index_lock(index_path: str):
    """An exclusive ``flock`` on ``<index>.lock`` for the block (none where ``fcntl`` is not)."""
    try:
        import fcntl
    except ImportError:                     # pragma: no cover - not POSIX
        yield
        return
    with open(index_path + ".lock", "ab") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _locked_save(self, key, data) -> None:
    """``numba``'s ``IndexDataCacheFile.save`` under :func:`_index_lock`: the index is read,
    a free data file name chosen, the data written, and then the index (a process loading the
    index without the lock finds an entry only once its data is there)."""
    with _index_lock(self._index_path):
        overloads = self._load_index()
        name = overloads.get(key)
        new = name is None
        if new:
            taken = set(overloads.values())
            name = next(n for n in map(self._data_name, itertools.count(1)) if n not in taken)
            overloads[key] = name
        self._save_data(name, data)
        if new:
            self._save_index(overloads)


caching.IndexDataCacheFile.save = _locked_save


_numba_load_overload = caching.Cache.load_overload


def _is_package_cache(cache) -> bool:
    """True when ``cache`` (a dispatcher's ``_cache``) is a package kernel's
    (:class:`PackageCacheLocator`); False for numba's in-tree caches and ``NullCache``."""
    impl = getattr(cache, "_impl", None)
    return impl is not None and isinstance(impl.locator, PackageCacheLocator)


def _load_without_refresh(self, sig, target_context):
    """numba's ``Cache.load_overload`` for the package's kernels without its first step, a
    refresh of the target context: that imports and installs every implementation registry
    numba has (~0.25 s at a process's first kernel, SciPy's BLAS among them), which only
    compiling needs, and numba's compile refreshes by itself. Loading cached machine code needs
    the runtime (NRT) its kernels call, initialised here. Other functions: numba's own."""
    if not _is_package_cache(self):
        return _numba_load_overload(self, sig, target_context)
    rtsys.initialize(target_context)
    with self._guard_against_spurious_io_errors():
        return self._load_overload(sig, target_context)


caching.Cache.load_overload = _load_without_refresh
kernel_loading.install(cache_dir, _write_whole)     # bitcode parsed when needed, the runtime's code kept


_numba_chain_init = Dispatcher._compilation_chain_init_hook


def _chain_init(self) -> None:
    """numba's hook at every call that looks for an overload (``_compile_for_args``), which
    first initialises the installed numba extensions (``entrypoints.init_all``: it reads every
    installed distribution's entry points, ~14 ms at a process's first kernel here) — for the
    package's kernels only where one is compiled (:class:`_LeanAtFirstCompile`): loading cached
    machine code and typing numpy arguments need no extension. Other functions: numba's own."""
    if not _is_package_cache(self._cache):
        _numba_chain_init(self)


Dispatcher._compilation_chain_init_hook = _chain_init


class _LeanAtFirstCompile(event.Listener):
    """At a process's first compile: installs :mod:`.lean_overloads` (a process that only loads
    cached kernels imports nothing for it), and initialises numba's extensions as numba's
    compilation hook would have (:func:`_chain_init`); numba's compile event comes before any
    typing."""

    def on_start(self, ev) -> None:
        entrypoints.init_all()
        lean_overloads.install()

    def on_end(self, ev) -> None:
        pass


event.register("numba:compile", _LeanAtFirstCompile())


# ---- compile notices and interruptible compiles ------------------------------------------------
class _Notices(event.Listener):
    """stderr lines while kernels compile: one line first, then one per compiled kernel."""

    def __init__(self, prog: str, stream=None, where: str = ""):
        self.prog = prog
        self.stream = stream
        self.where = f", {where}" if where else ""
        self.depth = 0
        self.started: float | None = None
        self.t0 = 0.0
        self.count = 0

    def _print(self, text: str) -> None:
        try:
            print(text, file=self.stream or sys.stderr, flush=True)
        except (OSError, ValueError):
            pass

    def on_start(self, ev) -> None:
        if self.depth == 0 and _refusing:
            disp = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            name = getattr(getattr(disp, "py_func", None), "__qualname__", "a kernel")
            raise CompileRefused(f"{name} is not in the kernel cache {cache_dir()}")
        if self.depth == 0:
            self.t0 = time.monotonic()
            if self.started is None:
                self.started = self.t0
                self._print(f"{self.prog}: compiling the simulation kernels (first run of this version on this "
                            f"machine; cached in {cache_dir()} for later runs) …")
            while _first_compile:
                try:
                    _first_compile.pop(0)()
                except Exception:       # noqa: BLE001 - a callback's failure must not fail the compile
                    pass
        self.depth += 1

    def on_end(self, ev) -> None:
        self.depth -= 1
        if self.depth == 0:
            self.count += 1
            disp = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            name = getattr(getattr(disp, "py_func", None), "__qualname__", "kernel")
            now = time.monotonic()
            self._print(f"  compiled {name} in {now - self.t0:.1f} s ({now - self.started:.0f} s so far{self.where})")


_numba_compile = Dispatcher.compile
_local = threading.local()
_notices: _Notices | None = None

#: the collector's thresholds while kernels compile (the process's own are restored after the
#: outermost compile). Cold ``run default``, three alternating pairs: default thresholds 22.1–23.5 s,
#: these 20.6–21.3 s (peak memory 364 → 380 MB; the collector off: 20.4–20.8 s, 584 MB)
COMPILE_GC_THRESHOLD = (100_000, 50, 1000)
_gc_lock = threading.Lock()
_gc_depth = 0
_gc_saved = gc.get_threshold()


def _sparse_gc_compile(self, sig):
    """numba's ``Dispatcher.compile`` with ``COMPILE_GC_THRESHOLD`` in force (nested compiles of
    callees inside it included); first, for a kernel of :func:`compiled_elsewhere`, the wait
    for the process that compiles it (numba's compile then loads it from the cache)."""
    global _gc_depth, _gc_saved
    wait = _elsewhere.pop(self, None) if _elsewhere else None
    if wait is not None:
        wait()
    with _gc_lock:
        if _gc_depth == 0:
            _gc_saved = gc.get_threshold()
            gc.set_threshold(*COMPILE_GC_THRESHOLD)
        _gc_depth += 1
    try:
        return _numba_compile(self, sig)
    finally:
        with _gc_lock:
            _gc_depth -= 1
            if _gc_depth == 0:
                gc.set_threshold(*_gc_saved)


Dispatcher.compile = _sparse_gc_compile


class CompileAbandoned(Exception):
    """A thread stopped waiting for a kernel compile (:func:`abandon_compiles_when`)."""


@contextmanager
def abandon_compiles_when(stop: threading.Event):
    """In this (non-main) thread, for the block: a kernel compile runs on a helper thread and
    the wait for it ends with :class:`CompileAbandoned` once ``stop`` is set (a reader thread
    whose consumer stopped need not finish a compile of seconds first). Needs
    :func:`compile_notices` installed; otherwise the block just runs."""
    old = getattr(_local, "abandon", None)
    _local.abandon = stop
    try:
        yield
    finally:
        _local.abandon = old


def _compile_off_main(self, sig):
    """``Dispatcher.compile`` of a main-thread call run on a helper thread: the main thread
    waits in short, interruptible waits, so a signal handler raising there (StopSignals) ends
    the wait at once; the helper is a daemon and dies with the process. The same for a thread
    inside :func:`abandon_compiles_when`, whose wait ends when its event is set."""
    main = threading.current_thread() is threading.main_thread()
    abandon = getattr(_local, "abandon", None)
    if (not main and abandon is None) or getattr(_local, "busy", False):
        return _sparse_gc_compile(self, sig)
    result: list = []

    def work() -> None:
        _local.busy = True
        try:
            result.append((True, _sparse_gc_compile(self, sig)))
        except BaseException as e:          # noqa: BLE001 - handed to the main thread
            result.append((False, e))

    th = threading.Thread(target=work, name="gyro-compile", daemon=True)
    th.start()
    while th.is_alive():
        th.join(0.05)
        if main:
            StopSignals.raise_held()        # a signal inside a deferred block: the compile has changed nothing
        elif abandon.is_set():
            raise CompileAbandoned(f"compile of {self.py_func.__qualname__} abandoned: the consumer stopped")
    ok, value = result[0]
    if ok:
        return value
    raise value


_first_compile: list = []                  # callables for the next first compile (when_compiling)
_elsewhere: dict = {}                       # dispatcher -> wait() (compiled_elsewhere)
_refusing = 0                               # nesting of compiles_refused blocks


class CompileRefused(Exception):
    """Inside :func:`compiles_refused`: a kernel this call needs is not in the cache (nothing
    was compiled; kernels loaded before it stay loaded)."""


def can_refuse_compiles() -> bool:
    """:func:`compiles_refused` works in this process (:func:`compile_notices` is installed)."""
    return _notices is not None


@contextmanager
def compiles_refused():
    """For the block: a kernel call that would compile raises :class:`CompileRefused` instead
    (kernels in the cache load and run as usual), so that a caller can tell a cold cache within
    milliseconds and do something else than wait (``engine.remote``). Needs
    :func:`compile_notices` (:func:`can_refuse_compiles`); without it the block compiles."""
    global _refusing
    _refusing += 1
    try:
        yield
    finally:
        _refusing -= 1


def when_compiling(callback) -> bool:
    """Call ``callback()`` once, when this process next starts compiling a kernel (at once if
    it is compiling now). Needs :func:`compile_notices` installed; False (and nothing is
    registered) without it. :func:`not_when_compiling` takes it back."""
    if _notices is None:
        return False
    if _notices.depth > 0:
        callback()
    else:
        _first_compile.append(callback)
    return True


def not_when_compiling(callback) -> None:
    """Take back a callback of :func:`when_compiling` that has not run."""
    if callback in _first_compile:
        _first_compile.remove(callback)


def compiled_elsewhere(dispatcher, wait: Callable[[], None] | None) -> None:
    """Another process compiles kernel ``dispatcher`` into the cache for this one: the next time
    this process would compile it, it first calls ``wait()`` (which returns once that process
    has ended), then loads the kernel from the cache, or compiles it after all when it is not
    there. ``wait=None`` takes it back."""
    if wait is None:
        _elsewhere.pop(dispatcher, None)
    else:
        _elsewhere[dispatcher] = wait


def notices_prog() -> str | None:
    """The command name :func:`compile_notices` was installed with (None: not installed)."""
    return None if _notices is None else _notices.prog


def quiet_compile_header() -> None:
    """No first line from :func:`compile_notices` in this process (another process of the same
    command said it): the per-kernel lines only."""
    if _notices is not None and _notices.started is None:
        _notices.started = time.monotonic()


def compile_notices(prog: str, stream=None, where: str = "") -> None:
    """From now on in this process: compile notices on stderr (``prog``: the command's name;
    ``where``: said on each kernel's line, e.g. which helper process) and interruptible compiles
    (see module doc). Idempotent (the first ``prog`` stays)."""
    global _notices
    if _notices is None:
        _notices = _Notices(prog, stream, where)
        event.register("numba:compile", _notices)
        Dispatcher.compile = _compile_off_main
