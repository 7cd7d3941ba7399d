"""The main job's report renders a window solved for every character when there is one."""
import pandas as pd

from convsynth_jax.tasks.main import _pick_window


def test_a_window_solved_for_both_characters_comes_first():
    c = pd.DataFrame({"condition": ["all"] * 4 + ["no_lr"] * 2, "window": [0, 0, 1, 1, 0, 0],
                      "character": ["female", "male"] * 3, "success": [True, False, True, True, True, True]})
    assert _pick_window(c, ["all", "no_lr"]) == ("all", 1, True)       # not window 0, where only one was solved
    c.loc[2, "success"] = False
    assert _pick_window(c, ["all", "no_lr"]) == ("no_lr", 0, True)     # another condition before a half-solved one
    c["success"] = [True, False, False, False, False, False]
    assert _pick_window(c, ["all", "no_lr"]) == ("all", 0, False)      # none for both: the first for one, said so
    assert _pick_window(c.iloc[:0], ["all"]) == ("all", 0, False)
