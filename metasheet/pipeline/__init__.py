"""The pipeline layer: configs, the stage registry, caching, manifests. The only layer doing file I/O."""
