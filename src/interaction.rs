//! Interaction with the cloth: picking particles with a ray, dragging them, cutting them.
//!
//! Everything here is built on request and cached: a step never pays for it.

/// Cached picking structures and the current grab; empty until a query asks for them.
#[derive(Default)]
pub struct InteractionState {}
