import os
import sys

from hcmt.cli import main

code = main()
if code in (130, 143):  # interrupted (Ctrl-C 130, SIGTERM 143): what it keeps is saved; an import cut short by the
    # signal must not re-raise KeyboardInterrupt at exit (seen: exit -2 instead of 143 when SIGTERM came during imports)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
raise SystemExit(code)
