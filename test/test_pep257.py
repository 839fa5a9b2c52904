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

"""ament_pep257 over the package, as ``ros2 pkg create`` sets it up (``colcon test`` runs it).

The 'ament' convention plus the project's documented deviations, read from ``setup.cfg``
``[ament_pep257] add-ignore`` (docs/style.md): the summary starts on the first line of the
docstring and may run on; the closing quotes follow the text.
"""
import configparser

import pytest

import rosenv


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(ros):
    cfg = configparser.ConfigParser()
    cfg.read(rosenv.REPO / "setup.cfg")
    ignore = cfg["ament_pep257"]["add-ignore"].split(",")
    p = ros.run(["ament_pep257", "--add-ignore", *ignore, "--", *rosenv.LINT_PATHS], timeout=600)
    assert p.returncode == 0, f"ament_pep257 found docstring style errors:\n{p.stdout[-8000:]}{p.stderr[-2000:]}"
