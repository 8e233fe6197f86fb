"""Property-based tests that feed random and mutated outside input to decoders and parsers."""
