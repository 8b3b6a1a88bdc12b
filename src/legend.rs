//! Drawing the palette legend image.
