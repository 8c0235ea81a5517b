"""What every study shares: its common options and the folders it reads and writes (``options``:
``Folders``), and the sweep that trains its runs in parallel (``sweep``)."""
