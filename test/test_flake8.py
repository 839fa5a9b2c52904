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

"""ament_flake8 over the package, as ``ros2 pkg create`` sets it up (``colcon test`` runs it).

ROS 2's ament_flake8 configuration with the project's documented deviations, both in
``setup.cfg`` ``[flake8]`` (docs/style.md): lines up to 120 characters, double quotes, and
docstrings whose summary starts on the first line and may run on (D205, D209, D400, D401).
"""
import pytest

import rosenv


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(ros):
    p = ros.run(["ament_flake8", "--config", str(rosenv.REPO / "setup.cfg"), *rosenv.LINT_PATHS], timeout=600)
    assert p.returncode == 0, f"ament_flake8 found code style errors:\n{p.stdout[-8000:]}{p.stderr[-2000:]}"
