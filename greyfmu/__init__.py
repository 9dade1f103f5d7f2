"""greyfmu: grey models, advanced process controllers and plants as plain numerical classes."""
