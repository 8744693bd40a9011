"""Pictures: the offscreen renderer, `viewer-bridge snapshot`, and the render server for Drake's
glTF render client."""
