"""One module per scene family; each defines ``SCENES`` (a list of ``scenes.registry.SceneEntry``)."""
