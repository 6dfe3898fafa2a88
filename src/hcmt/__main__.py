from hcmt.cli import main

raise SystemExit(main())
