"""What every study shares: its common options and folders (``options``) and the sweep that
trains its runs in parallel (``sweep``)."""
