"""The seed paper's reproduction: its figures (``figures``), its statements checked (``checks``), the command; and the
model against a published measurement (``anchor``, the physics alone)."""
