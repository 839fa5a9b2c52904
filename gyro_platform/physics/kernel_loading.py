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

"""What a process pays to load cached kernels, less (imports numba, llvmlite and numpy only;
installed by ``jit``).

numba loads a cached kernel as its machine code plus, beside it, the kernel's LLVM bitcode (the
"module for linking", which only a kernel compiled later in the process and calling this one
needs), and it parses that bitcode at once to list the symbols it defines; and at a process's
first kernel it compiles the helper functions of its runtime (NRT) from LLVM IR. Measured on a
new process's replay of the 1 kHz bag (10 kernels loaded): 28 ms parsing bitcode, 12 ms listing
its symbols, 22 ms compiling the runtime, of ~0.2 s the first replay in a process takes more
than the next.

* :func:`install` ``(folder)`` patches numba so that a cached kernel's bitcode is parsed only
  when it is needed: when a kernel being compiled links this one
  (``CPUCodeLibrary._get_module_for_linking``), or when numba asks whether a name it does not
  know yet is defined (``JitEngine.is_symbol_defined``: the pending kernels' symbols are listed
  then, as numba would have listed them at load). The one question a load asks, the address of
  the kernel's own entry points (numba's mangled names, ``_ZN…``), is answered by the execution
  engine, which has the machine code's symbols (``CPUCodeLibrary.get_pointer_to_function``);
  anything else is numba's own path.
* The runtime's helper library is compiled once per code version and CPU and kept as machine
  code in ``folder()``/``nrt-<digest of numba's CPU key>.nbl`` (``nrtdynmod.compile_nrt_functions``);
  a missing, damaged or foreign file is compiled again and rewritten.
* numba's type of an array argument (``typeof`` of an ``ndarray``, at a kernel's first call in a
  process, before the cache is looked up) first asks whether it is a masked array,
  ``isinstance(val, np.ma.MaskedArray)``, and with numpy 2 that attribute imports ``numpy.ma``:
  ~20 ms of every process's first kernel call here. :func:`_typeof_ndarray` asks it only where
  ``numpy.ma`` is imported (no masked array exists before) or the array is of a subclass
  (numba's own then); a plain array gets numba's type, built as numba builds it.

* A cached kernel's environments (numba's per-function record of the module globals and
  constant objects the compiled code may ask for at run time) are rebuilt at load by importing
  the module of each function (``environment._rebuild_env``), numba's own library modules
  included: loading the replay's kernels imported ``numba.np.arrayobj`` (with numba's string
  and hashing code, ~23 ms) for the array functions compiled into them (whether kernels carry
  such environments depends on the build: those built here on 2026-11-29 with numba 0.63 or
  0.68 carry none). Only object-mode code reads an environment's globals; the package's
  kernels are nopython, and numba's library functions in them too. :func:`_rebuild_env` gives
  an environment of a numba module not yet imported the module's name alone as its globals
  (what numba writes when it caches it again), and its constants as numba does; any other
  module is imported as numba does.

Results are the same machine code: the kernels are numba's cached ones and the runtime's is
what numba compiled for this CPU. ``GYRO_PLATFORM_LAZY_LOAD=0``, or a numba without the pieces
patched (:func:`_fits_this_numba`), leaves numba as it is.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
import pickle
import sys
from typing import Callable
import weakref

import llvmlite.binding as ll
from numba.core import codegen as _codegen, environment as _environment, errors as _errors, types as _types
from numba.core.runtime import nrtdynmod
from numba.core.typing import typeof as _typeof
from numba.np import numpy_support as _np_support
import numpy as np

__all__ = ["install", "nrt_path"]

_Library = _codegen.CPUCodeLibrary
_numba_unserialize = _Library._unserialize.__func__
_numba_module_for_linking = _Library._get_module_for_linking
_numba_pointer_to_function = _codegen.JITCodeLibrary.get_pointer_to_function
_numba_is_symbol_defined = _codegen.JitEngine.is_symbol_defined
_numba_rebuild_env = _environment._rebuild_env

_folder: Callable[[], Path] | None = None
_write: Callable[[Path, Callable], bool] | None = None


def _unserialize(cls, codegen, state):
    """numba's ``_unserialize`` of a cached library, its bitcode kept unparsed (see module doc)."""
    name, kind, data = state
    if kind != "object" or not (isinstance(data, tuple) and len(data) == 2):
        return _numba_unserialize(cls, codegen, state)
    object_code, shared_bitcode = data
    self = codegen.create_library(name)
    self.enable_object_caching()
    self._set_compiled_object(object_code)
    self._lazy_bitcode = shared_bitcode
    self._lazy_loaded = True
    self._finalize_final_module()           # the machine code into the execution engine
    engine = codegen._engine
    engine.__dict__.setdefault("_pending_libraries", []).append(weakref.ref(self))
    return self


def _module_for_linking(self):
    """numba's, the cached bitcode parsed the first time it is asked for."""
    bitcode = self.__dict__.pop("_lazy_bitcode", None)
    if bitcode is not None:
        self._shared_module = ll.parse_bitcode(bitcode)
    return _numba_module_for_linking(self)


def _is_symbol_defined(self, name):
    """numba's answer, the symbols of the kernels loaded meanwhile listed first when ``name`` is
    not known yet."""
    if name in self._defined_symbols:
        return True
    pending = self.__dict__.get("_pending_libraries")
    if pending:
        self._pending_libraries = []
        for ref in pending:
            library = ref()
            if library is not None:
                self._load_defined_symbols(library._get_module_for_linking())
    return _numba_is_symbol_defined(self, name)


def _pointer_to_function(self, name):
    """The address of a numba function (a mangled ``_ZN…`` name) from the execution engine for a
    library loaded from the cache; numba's path for any other name or library."""
    if "_lazy_loaded" in self.__dict__ and name.startswith("_ZN"):
        self._ensure_finalized()
        address = self._codegen._engine.get_function_address(name)
        if address:
            return address
    return _numba_pointer_to_function(self, name)


def _rebuild_env(modname, consts, env_name):
    """numba's ``_rebuild_env``, without importing a numba module for it (see module doc)."""
    env = _environment.lookup_environment(env_name)
    if env is not None:
        return env
    if not (isinstance(modname, str) and modname.startswith("numba.")) or modname in sys.modules:
        return _numba_rebuild_env(modname, consts, env_name)
    env = _environment.Environment({"__name__": modname})
    env.consts[:] = consts
    env.env_name = env_name
    _environment.Environment._memo[env_name] = env
    return env


def nrt_path(codegen) -> Path:
    """The file of the runtime's helper library for this code version and ``codegen``'s CPU."""
    key = repr((codegen.magic_tuple(), ll.llvm_version_info)).encode()
    return _folder() / f"nrt-{hashlib.sha256(key).hexdigest()[:20]}.nbl"


def _compile_nrt(ctx):
    """numba's ``compile_nrt_functions``, loaded from :func:`nrt_path` when it is there."""
    codegen = ctx.codegen()
    path = nrt_path(codegen)
    try:
        state = pickle.loads(path.read_bytes())
        if isinstance(state, tuple) and len(state) == 3 and state[1] == "object":
            return codegen.unserialize_library(state)
    except Exception:  # noqa: BLE001 — missing, damaged or foreign: compiled again below
        pass
    ir_mod, library = nrtdynmod.create_nrt_module(ctx)
    library.enable_object_caching()
    library.add_ir_module(ir_mod)
    library.finalize()
    try:
        state = library.serialize_using_object_code()
    except (ValueError, RuntimeError):     # not kept: compiled again next time
        return library
    _write(path, lambda f: f.write(pickle.dumps(state)))
    return library


_numba_typeof_ndarray = _typeof.typeof_impl.dispatch(np.ndarray)


def _typeof_ndarray(val, c):
    """numba's ``_typeof_ndarray`` without importing ``numpy.ma`` (see module doc)."""
    if type(val) is not np.ndarray or "numpy.ma" in sys.modules:
        return _numba_typeof_ndarray(val, c)
    try:
        dtype = _np_support.from_dtype(val.dtype)
    except _errors.NumbaNotImplementedError:
        raise _errors.NumbaValueError(f"Unsupported array dtype: {val.dtype}")
    return _types.Array(dtype, val.ndim, _np_support.map_layout(val), readonly=not val.flags.writeable)


def _fits_this_numba() -> bool:
    """True when numba has the pieces the patches stand in for (as numba 0.58–0.68 do); another
    numba keeps its own loading."""
    library = ("_unserialize", "_get_module_for_linking", "_set_compiled_object", "_finalize_final_module",
               "enable_object_caching")
    engine = ("is_symbol_defined", "_load_defined_symbols", "get_function_address")
    return (all(hasattr(_Library, a) for a in library) and all(hasattr(_codegen.JitEngine, a) for a in engine)
            and hasattr(nrtdynmod, "create_nrt_module") and hasattr(_environment.Environment, "_memo")
            and hasattr(_environment, "lookup_environment"))


def install(folder: Callable[[], Path], write_whole: Callable[[Path, Callable], bool]) -> bool:
    """Patch numba as the module doc says (once; not under ``GYRO_PLATFORM_LAZY_LOAD=0``).
    ``folder()``: the kernel cache folder in use; ``write_whole(path, write)``: a file written
    whole or not at all. True when installed."""
    global _folder, _write
    if os.environ.get("GYRO_PLATFORM_LAZY_LOAD") == "0" or not _fits_this_numba():
        return False
    _folder, _write = folder, write_whole
    _Library._unserialize = classmethod(_unserialize)
    _Library._get_module_for_linking = _module_for_linking
    _codegen.JITCodeLibrary.get_pointer_to_function = _pointer_to_function
    _codegen.JitEngine.is_symbol_defined = _is_symbol_defined
    nrtdynmod.compile_nrt_functions = _compile_nrt
    if getattr(_numba_rebuild_env, "__module__", "") == "numba.core.environment":
        _environment._rebuild_env = _rebuild_env
    if getattr(_numba_typeof_ndarray, "__name__", "") == "_typeof_ndarray":    # numba's, as in 0.58–0.68
        _typeof.typeof_impl.register(np.ndarray, _typeof_ndarray)
    return True
