"""Design timings: the structured (fixed-order, multi-model) design, the truncation chain
(H∞ synthesis + reduction + Tustin), and the 30-point robustness check; on the simulated
plant's truth (design model at 4000 rpm / 7 bar, design set over the operating range)."""

import time
import warnings


def run() -> dict:
    warnings.filterwarnings("ignore")
    from rigd.design import pipeline, robustness
    from rigd.design.weights import load_design_config
    from rigd_drivers.sim import truth as simtruth

    cfg = load_design_config("config/design.yaml")
    G = simtruth.plant_s(4000.0, 7.0)
    t0 = time.perf_counter()
    st, _ = pipeline.design(G, cfg, method="structured", plant_at=simtruth.plant_s,
                            compare=False)
    t1 = time.perf_counter()
    res = pipeline.design_controller(G, cfg)
    t2 = time.perf_counter()
    rob = robustness.analyze(simtruth.plant_z, res.K_z, cfg.robustness)
    t3 = time.perf_counter()
    s = rob.summary()
    ss = robustness.analyze(simtruth.plant_z, st.K_z, cfg.robustness).summary()
    return {"design_structured_s": t1 - t0, "design_structured_tuning_s": st.tuning["time_s"],
            "design_structured_order": st.order,
            "design_structured_gamma": st.gamma,
            "design_structured_models": st.tuning["n_models"],
            "design_structured_peak_max": ss["sensitivity_peak_max"],
            "design_structured_all_stable": ss["all_stable"],
            "design_chain_s": t2 - t1, "robustness_30_s": t3 - t2, "gamma": res.gamma,
            "controller_order": res.order, "sensitivity_reduction_min":
            s["sensitivity_reduction_min"], "sensitivity_peak_max": s["sensitivity_peak_max"]}
