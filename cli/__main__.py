import sys

from wearbench.cli import main

sys.exit(main())
