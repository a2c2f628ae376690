//! Procedural scenes: the `City` generator and small analytic test scenes.
