"""How many participants does a study need to show that ours is preferred?

Suppose ours wins 52% of the view choices and the better baseline 40% (the rest go to
the third method). The pairwise claim is tested by an exact binomial test on the
choices between the two; with two baselines, Holm's correction makes each test
stricter. Run: ``.venv/bin/python examples/analysis_power.py``.
"""

from analysis import sample_size

for comparisons in (1, 2):
    need = sample_size(0.52, 0.40, alpha=0.05, power=0.8, comparisons=comparisons)
    print(
        f"{comparisons} comparison(s): {need['n_stable']} participants "
        f"(power {need['power_at_n']:.2f} from there on)"
    )
