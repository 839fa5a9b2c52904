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
