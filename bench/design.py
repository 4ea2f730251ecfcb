"""Design chain timings: H∞ synthesis + reduction + Tustin, and the 30-point robustness check."""

import time
import warnings


def run() -> dict:
    warnings.filterwarnings("ignore")
    from rigd.design import pipeline, robustness, simtruth
    from rigd.design.weights import load_design_config

    cfg = load_design_config("config/design.yaml")
    G = simtruth.plant_s(4000.0, 7.0)
    t0 = time.perf_counter()
    res = pipeline.design_controller(G, cfg)
    t1 = time.perf_counter()
    rob = robustness.analyze(simtruth.plant_z, res.K_z, cfg.robustness)
    t2 = time.perf_counter()
    s = rob.summary()
    return {"design_chain_s": t1 - t0, "robustness_30_s": t2 - t1, "gamma": res.gamma,
            "controller_order": res.order, "sensitivity_reduction_min":
            s["sensitivity_reduction_min"], "sensitivity_peak_max": s["sensitivity_peak_max"]}
