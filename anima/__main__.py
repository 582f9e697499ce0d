import sys

from anima.cli.main import main

sys.exit(main())
