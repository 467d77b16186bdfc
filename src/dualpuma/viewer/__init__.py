"""Browser viewer (viser): `dualpuma serve`."""
