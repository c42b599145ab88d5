"""One typed scene, one builder, one step: the runtime every entry point uses."""
