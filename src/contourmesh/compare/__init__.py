"""Comparisons: the paper's reproduction and (later) the harness of mesh sources and post-processes."""
