"""File formats at the edge: everything here speaks mm and degrees and validates its input."""
