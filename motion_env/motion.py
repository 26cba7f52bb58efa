"""Pure motion math on the canonical skeleton (being written: see issue 2)."""
