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

"""``gyro-platform run SCENE [--out DIR] [--duration S] [--integrator NAME] [--max-step S]
[--no-files]``: run a scene (a YAML file or a shipped scene's name), print the summary table and
the expectation results. Exit status: 0 every expectation passes; 1 one fails or is not
evaluable, or the simulation failed; 2 bad scene, argument, bag path or output folder (checked
before the run), or a run beyond the size bounds (``schema.run_budget``); 3 damaged bag (the
readable part is run and written) or a bag that gave no usable sample; 4 the results could not
be written (disk full); 130/143 Ctrl-C/SIGTERM (no results are written)."""
from __future__ import annotations

from pathlib import Path
import sys

from .runner import run_scene
from .schema import load_scene, MotionError, ScenarioError
from ..errors import (BagPathError, BagReadError, EXIT_DATA, EXIT_FAILED, EXIT_OK, EXIT_USAGE, EXIT_WRITE, OutputError,
                      ReplayError, SimulationError)
from ..filesystem import check_output_path, write_failure
from ..reports.recording import print_summary_table


def print_results(results, file=None) -> None:
    """One line per expectation: PASS/FAIL, measured value, criterion, and why."""
    out = file if file is not None else sys.stdout
    for c, passed, detail in results:
        tag = "N/A " if passed is None else "PASS" if passed else "FAIL"
        print(f"{tag}  {detail}" + (f"   [{c.why}]" if c.why else ""), file=out)


def add_arguments(parser) -> None:
    parser.add_argument("scene", help="scene: a YAML file, or the name of a shipped scene (e.g. default, "
                                      "coning; the installed config/scenes folder)")
    parser.add_argument("--out", metavar="DIR", help="output folder (default results/<scene name>/)")
    parser.add_argument("--duration", type=float, metavar="S",
                        help="override the simulated duration (s); shorter than the scene's test_duration "
                             "(else duration) leaves the expectations not evaluable (exit 1)")
    parser.add_argument("--integrator", metavar="NAME", help="override the scene's integrator")
    parser.add_argument("--max-step", type=float, metavar="S", help="override the scene's max_step (s)")
    parser.add_argument("--no-files", action="store_true", help="write no CSV/JSON/PNG")


#: the files ``run`` writes into ``--out``
RESULT_FILES = ("outputs.csv", "summary.json", "plot.png")


def _error(message: str) -> None:
    print(f"gyro-platform run: error: {message}", file=sys.stderr)


def run(args) -> int:
    """``gyro-platform run``: exit 0 all expectations pass, 1 one fails or is not evaluable, or
    the run went through gimbal lock and a tighter check run disagrees (ill-conditioned), 2 bad
    scene, argument or bag path, 3 damaged bag (the readable part is run and written)."""
    try:
        scene = load_scene(args.scene)
        if args.duration is not None:
            scene = scene.with_duration(args.duration)
        if args.integrator is not None or args.max_step is not None:
            scene = scene.with_integrator(args.integrator, args.max_step)
    except ScenarioError as e:
        _error(str(e))
        return EXIT_USAGE
    out = None if args.no_files else Path(args.out) if args.out else Path("results") / scene.name
    if out is not None:
        try:
            check_output_path(out, "--out", files=RESULT_FILES)
        except OutputError as e:
            _error(str(e))
            return EXIT_USAGE
    print(f"scene {scene.name}: {scene.description}".rstrip(": "))
    try:
        _, summary, results = run_scene(scene, out_dir=out)
    except (BagPathError, ReplayError) as e:
        _error(f"scene '{scene.name}': {e}")
        return EXIT_USAGE
    except MotionError as e:            # a synthetic motion beyond floating point: nothing written
        _error(str(e))
        return EXIT_USAGE
    except ScenarioError as e:          # raised by a run only when the bag gave no usable sample
        _error(str(e))
        return EXIT_DATA
    except BagReadError as e:
        _error(f"scene '{scene.name}': {e}")
        return EXIT_DATA
    except SimulationError as e:
        _error(f"scene '{scene.name}': simulation failed: {e}")
        return EXIT_FAILED
    except Exception as e:              # noqa: BLE001 - disk full, file size limit while writing
        why = write_failure(e)
        if why is None:
            raise
        _error(f"cannot write the results to {out}: {why}")
        return EXIT_WRITE
    print_summary_table(summary)
    if summary.get("max_error_norm") is not None:
        print(f"integrator {summary['integrator']}: largest local error estimate "
              f"{summary['max_error_estimate']:.3g} (state units), {summary['max_error_norm']:.3g} × the asked "
              f"tolerance (rtol {scene.options.rtol:g}, atol {scene.options.atol:g})")
    for w in summary.get("warnings", []):
        print(f"warning: {w}")
    if results:
        print("expectations:")
        print_results(results)
    if out is not None:
        print(f"wrote {out / 'outputs.csv'}, {out / 'summary.json'}, {out / 'plot.png'}")
    if summary.get("error"):
        _error(f"scene '{scene.name}': {summary['error']}")
        return EXIT_DATA
    n_na = sum(1 for _, p, _ in results if p is None)
    n_fail = sum(1 for _, p, _ in results if p is False)
    if n_na:
        print(f"{n_na} of {len(results)} expectation(s) NOT EVALUABLE")
    if n_fail:
        print(f"{n_fail} of {len(results)} expectation(s) FAILED")
    ill = summary.get("gimbal_lock_check", {}).get("ill_conditioned")
    if ill:
        _error(f"scene '{scene.name}': ill-conditioned: the outputs from t = "
               f"{summary['gimbal_lock_check']['t_beyond']:.6g} s are not held to the asked tolerance "
               "(gimbal lock, see the warning above)")
    return EXIT_FAILED if n_fail or n_na or ill else EXIT_OK
