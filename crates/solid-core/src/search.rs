//! Exact nearest-neighbour search over R-SOLiD vectors (issue 3; in progress).
