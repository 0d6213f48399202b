//! Pictures: shaded meshes ([`render`]) and line charts of tables ([`plot`]), as PNG.

pub mod plot;
pub mod render;
