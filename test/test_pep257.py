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
