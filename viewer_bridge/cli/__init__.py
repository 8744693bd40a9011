"""The command line, `viewer-bridge`: one module per job of it (`main` parses and dispatches)."""
