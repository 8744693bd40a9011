"""`python -m viewer_bridge`: the command line, as `viewer-bridge` runs it."""

from viewer_bridge.cli.main import main

raise SystemExit(main())
