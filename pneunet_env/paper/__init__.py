"""The seed paper's reproduction: its figures (``figures``), its statements checked (``checks``), the command."""
