"""``metasheet serve``: drive a pipeline's robot live from a browser.

Modules, one concept each:

* :mod:`.loading`: the robot of a pipeline's outputs, as the robot stage built it (the one
  place a robot model, "full" or "reduced", is chosen);
* :mod:`.tracking`: one goal driven control step by control step (``goto``'s loop, cut);
* :mod:`.session`: the shared robot state and the solver thread (no web code: unit-tested);
* :mod:`.scene`: what is drawn of a state (surface colour bands, horns, rod, fibres);
* :mod:`.panel`: the status panel's text and the update-rate meter;
* :mod:`.maze`: the maze stage's motor series, for playback;
* :mod:`.app`: the web page (viser) and :func:`.app.serve`.
"""
