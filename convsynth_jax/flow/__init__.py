"""A learned co-speech peer: conditional flow matching over motion features from the speaker's and the
partner's audio (``model.py``: the objective, the network, training and sampling; ``features.py``:
what it reads and writes). Independent of the motion graph's code."""
