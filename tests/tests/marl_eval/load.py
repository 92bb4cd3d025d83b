"""Loads a `harness export marl-eval` file with marl-eval's own code, as its users do.

Usage: python load.py EXPORT.json OUT_DIR
Exits non-zero, naming the check, when marl-eval rejects the file or computes no score.
"""

import json
import math
import sys

import matplotlib

matplotlib.use("Agg")

from marl_eval.plotting_tools.plotting import aggregate_scores  # noqa: E402
from marl_eval.utils.data_processing_utils import (  # noqa: E402
    create_matrices_for_rliable,
    data_process_pipeline,
)
from marl_eval.utils.diagnose_data_errors import DiagnoseData  # noqa: E402

ENVIRONMENT = "vpm"
METRICS = ["return"]


def main(export, out_dir):
    with open(export) as f:
        raw = json.load(f)
    checks = DiagnoseData(raw).check_data()
    failed = {
        f"{env}.{name}": value
        for env, results in checks.items()
        for name, value in results.items()
        if value is not True
    }
    assert checks and not failed, f"DiagnoseData: {failed or 'no environment'}"
    processed = data_process_pipeline(raw_data=raw, metrics_to_normalize=METRICS)
    # The pipeline prints its errors and returns the raw data instead of raising.
    assert "extra" in processed, "data_process_pipeline rejected the file"
    matrices, _ = create_matrices_for_rliable(
        data_dictionary=processed,
        environment_name=ENVIRONMENT,
        metrics_to_normalize=METRICS,
    )
    # Its score table turns the scores into text in place; the intervals stay numbers.
    _, _, intervals = aggregate_scores(
        matrices,
        metric_name="return",
        metrics_to_normalize=METRICS,
        tabular_results_file_path=f"{out_dir}/aggregated_score",
    )
    algorithms = processed["extra"]["algorithm_list"]
    assert len(intervals) == len(algorithms), f"scores of {sorted(intervals)}, not {algorithms}"
    for algorithm, by_statistic in intervals.items():
        for statistic, (low, high) in by_statistic.items():
            assert math.isfinite(low) and math.isfinite(high) and low <= high, (
                f"{algorithm} {statistic}: interval [{low}, {high}]"
            )
    print(
        f"marl-eval: {len(algorithms)} algorithms, "
        f"{len(processed['extra']['environment_list'][ENVIRONMENT])} tasks, "
        f"{processed['extra']['number_of_runs']} runs each; aggregate scores computed"
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
