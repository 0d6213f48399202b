//! Line charts from tables.
