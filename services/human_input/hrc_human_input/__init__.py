"""hrc-cosim human input: scripted participant, replay, live VR bridge, recording."""
