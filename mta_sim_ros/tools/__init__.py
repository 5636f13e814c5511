"""Command-line tools around the simulator (``mta <command>``)."""
