"""Service layer: settings, composition root, command-line interface, the long-running monitor."""
