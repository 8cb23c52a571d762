"""Wood representation: skeleton graph, cross-section profiles and strands (docs/model.md §1-2)."""
