"""Walk the Talk (Wang et al.): gestures spliced onto walking and jogging loops, synchronized to the
locomotion contact phase and the utterance; docs/walktalk.md."""
