import os
import sys

from hcmt.cli import main

code = main()
if code == 130:  # interrupted (Ctrl-C, SIGTERM): what it keeps is saved; an import cut short must not re-raise at exit
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
raise SystemExit(code)
