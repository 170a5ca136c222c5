"""What the animator sees: the sidebar panel and menu, the viewport overlay, the scene settings."""
