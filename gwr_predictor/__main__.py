"""`python -m gwr_predictor ...` is the same as the `gwr-predictor` command."""

from gwr_predictor.commands.cli import main

raise SystemExit(main())
