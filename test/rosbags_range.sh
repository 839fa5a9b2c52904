#!/usr/bin/env bash
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

# The bag tests against the rosbags versions setup.py allows, each in a throwaway venv.
#
#   test/rosbags_range.sh [low|high|VERSION ...]      (default: low high)
#
# low: the lowest version setup.py pins (rosbags>=X); high: the newest release below its cap
# (<Y); VERSION: that release. Venvs go to ${RANGE_DIR:-/tmp}/rosbags-<spec> (kept, reused);
# PYTHON picks the interpreter (default python3). The package is used from this checkout
# (PYTHONPATH), never installed, so nothing else in the environment is seen.
set -euo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd)
PY=${PYTHON:-python3}
DIR=${RANGE_DIR:-/tmp}
SPEC=$(grep -o '"rosbags[^"]*"' "$REPO/setup.py" | tr -d '"')      # e.g. rosbags>=0.11.6,<0.12
LOW=$(sed -n 's/.*>=\([0-9.]*\).*/\1/p' <<<"$SPEC")
TESTS=(test/test_bag_writer.py test/test_bag_chunks.py test/test_replay.py test/test_faults.py)
DEPS=(numpy numba scipy matplotlib pyyaml apsw mcap zstandard lz4 "backports.zstd; python_version < '3.14'" tqdm threadpoolctl ruamel.yaml.clib pytest hypothesis)

[ $# -gt 0 ] || set -- low high
status=0
for want in "$@"; do
    case $want in
        low) req="rosbags==$LOW" ;;
        high) req=$SPEC ;;
        *) req="rosbags==$want" ;;
    esac
    venv=$DIR/rosbags-$want
    [ -x "$venv/bin/python" ] || "$PY" -m venv "$venv"
    "$venv/bin/pip" install -q --upgrade "${DEPS[@]}" "$req"
    got=$("$venv/bin/python" -c 'import importlib.metadata as m; print(m.version("rosbags"))')
    echo "== rosbags $got ($want: $req)"
    if (cd "$REPO" && PYTHONPATH=$REPO nice -n 10 "$venv/bin/python" -m pytest -q -p no:cacheprovider "${TESTS[@]}"); then
        echo "== rosbags $got: passed"
    else
        echo "== rosbags $got: FAILED"
        status=1
    fi
done
exit $status
