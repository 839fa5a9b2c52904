"""ament_copyright over the package, as ``ros2 pkg create`` sets it up (``colcon test`` runs it):
every source file carries the copyright notice and the Apache-2.0 header of package.xml."""
import pytest

import rosenv


@pytest.mark.copyright
@pytest.mark.linter
def test_copyright(ros):
    p = ros.run(["ament_copyright", *rosenv.LINT_PATHS], timeout=600)
    assert p.returncode == 0, f"ament_copyright: files without the notice:\n{p.stdout[-8000:]}{p.stderr[-2000:]}"
