"""Image creatures: video made by a behaviour system walking a graph of frames (thesis,
"ozymandias (video)", "off-line image processing – image creatures").

:mod:`footage` reads the frames (a colony's own renders, a supplied video, or the generated
rotating cube of the thesis's figures), :mod:`image_graph` builds the tangled directed graph
of frames, :mod:`walker` is the trivial behaviour system the audio EDL drives along it, and
:mod:`video` composes each output frame with motion blur and writes the video.
"""
