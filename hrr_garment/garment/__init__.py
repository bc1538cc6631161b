"""Garments: templates fitted to the body, mesh checks and repairs, attachment, OBJ."""
