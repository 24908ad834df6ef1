"""The paper's Table 2 with honest statistics: which view did its 100 participants prefer?

The counts are the paper's own (package data). Ours against each baseline by exact
binomial tests, Holm-corrected over all twelve scene × baseline tests, at α = 0.05.
Run: ``.venv/bin/python examples/analysis_paper_table2.py``.
"""

from analysis import claim_summary, ours_vs_baselines, paper_counts, vote_table

counts = paper_counts()  # scenes × methods (ours, viewpoint_entropy, motion_area)
print(counts, end="\n\n")

shares = vote_table(counts)  # votes, share and its Wilson 95% interval per method
print(shares[["scene", "method", "votes", "share", "ci_low", "ci_high"]].round(3), end="\n\n")

tests = ours_vs_baselines(counts)  # exact binomial, Holm over the family of 12 tests
print(tests[["scene", "baseline", "reference_votes", "baseline_votes", "p_holm", "verdict"]])
print()
for sentence in claim_summary(tests):
    print(sentence)

wins = tests[tests["significant"] & (tests["verdict"] == "ours preferred")]
by_baseline = wins.groupby("baseline").size().to_dict()
print(f"\nours significantly preferred: {by_baseline} (of {len(counts)} animations each)")
