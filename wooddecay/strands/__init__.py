"""Wood representation: skeleton graph, cross-section profiles and strands (SPEC §1-2)."""
