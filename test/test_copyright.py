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

"""ament_copyright over the package, as ``ros2 pkg create`` sets it up (``colcon test`` runs it):
every source file carries the copyright notice and the Apache-2.0 header of package.xml."""
import pytest

import rosenv


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright(ros):
    p = ros.run(["ament_copyright", *rosenv.LINT_PATHS], timeout=600)
    assert p.returncode == 0, f"ament_copyright: files without the notice:\n{p.stdout[-8000:]}{p.stderr[-2000:]}"
