"""``python -m gyro_platform`` = ``gyro-platform``."""
import sys

from .cli import main

sys.exit(main())
