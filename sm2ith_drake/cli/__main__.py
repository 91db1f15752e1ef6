import sys

from sm2ith_drake.cli.main import main

sys.exit(main())
