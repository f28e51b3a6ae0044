//! Reference simulator (being written).
