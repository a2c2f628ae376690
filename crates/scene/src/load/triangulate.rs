//! Triangulation of polygons (in progress).
