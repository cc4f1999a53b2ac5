"""3GPP TR 37.885 V2V channel (section 6.2) as a predictor for the three tasks.

The reference is the project's C++ (generators/sinr/channel_models.cpp, namespace formulas), which
the SINR generator's tr37885-* channel models use; every constant here is the same:
  - LOS probability, TR 37.885 Table 6.2-1 (section 6.2.1): urban min(1, 1.05 exp(-0.0114 d));
    highway d <= 475 m: min(1, 2.1013e-6 d^2 - 0.002 d + 1.0193), else max(0, 0.54 - 0.001 (d - 475)).
  - NLOS probability (same table): urban 1 / (0.0312 d) exp(-(ln d - 5.0063)^2 / 2.4544), clamped so
    the three states sum to 1; highway 0 (two states: LOS and NLOSV). NLOSV = 1 - P_LOS - P_NLOS.
    The state probabilities take the 2-D distance, the path losses the 3-D distance (as the C++).
  - Path loss, Table 6.2.1-1: urban LOS/NLOSV 38.77 + 16.7 log10 d + 18.2 log10 fc; highway
    LOS/NLOSV 32.4 + 20 log10 d + 20 log10 fc; NLOS 36.85 + 30 log10 d + 18.9 log10 fc (fc in GHz).
  - NLOSV blockage loss, section 6.2.1 (vehicle blockage): extra = max(0, 15 log10 d - 41);
    both antennas above the blocker: 0 dB; both below: N(9 + extra, 4.5); else N(5 + extra, 4.0);
    the drawn loss is clipped at 0 dB. Antenna 1.5 m and blocker 1.6 m (the C++ defaults, or the
    SINR run's antenna_height_m / blocker_height_m), so vehicles block with N(9 + extra, 4.5).
  - Shadowing: log-normal, sigma 3 dB in LOS and 4 dB otherwise (the C++ uses 4 dB for NLOSV; the
    table gives NLOSV the LOS value 3 dB: kept as the C++ so the two agree).
  - Distances are clamped to at least 3 m (TR 36.885: the path loss at 3 m below 3 m).
"""
import numpy as np
from scipy.special import ndtr

MIN_DISTANCE_M = 3.0
ANTENNA_HEIGHT_M = 1.5
BLOCKER_HEIGHT_M = 1.6

# Scenario per city (TR 37.885 6.2: urban grid or highway); unknown cities default to urban.
CITY_SCENARIO = {"demo": "urban", "badhersfeld": "urban", "van3twin-ring": "urban"}


def scenario_of(city):
    return CITY_SCENARIO.get(city, "urban")


def p_los(scenario, d):
    d = np.asarray(d, float)
    if scenario == "urban":
        return np.minimum(1.0, 1.05 * np.exp(-0.0114 * d))
    near = np.minimum(1.0, 2.1013e-6 * d * d - 0.002 * d + 1.0193)
    far = np.maximum(0.0, 0.54 - 0.001 * (d - 475.0))
    return np.where(d <= 475.0, near, far)


def p_nlos(scenario, d):
    d = np.asarray(d, float)
    if scenario == "highway":
        return np.zeros_like(d)
    l = np.log(d) - 5.0063
    p = 1.0 / (0.0312 * d) * np.exp(-(l * l) / 2.4544)
    # The fitted curve can exceed what LOS leaves; the probabilities must sum to 1.
    return np.clip(p, 0.0, 1.0 - p_los(scenario, d))


def class_probabilities(scenario, d2):
    """(n, 3) probabilities of LOS, NLOSV, NLOS at 2-D distance d2."""
    d2 = np.maximum(MIN_DISTANCE_M, np.asarray(d2, float))
    pl, pn = p_los(scenario, d2), p_nlos(scenario, d2)
    return np.stack([pl, 1.0 - pl - pn, pn], axis=1)


def pathloss_db(scenario, los_class, d, fc_hz):
    """Path loss per state; NLOSV gives the LOS value (its blockage loss is added separately)."""
    d = np.maximum(MIN_DISTANCE_M, np.asarray(d, float))
    ld, lf = np.log10(d), np.log10(fc_hz * 1e-9)
    los = (32.4 + 20.0 * ld + 20.0 * lf) if scenario == "highway" else (38.77 + 16.7 * ld + 18.2 * lf)
    return np.where(np.asarray(los_class) >= 2, 36.85 + 30.0 * ld + 18.9 * lf, los)


def nlosv_blockage(d, h_tx=ANTENNA_HEIGHT_M, h_rx=ANTENNA_HEIGHT_M, h_blocker=BLOCKER_HEIGHT_M):
    """(mean_db, sigma_db) of the NLOSV blockage loss before clipping at 0 dB."""
    d = np.maximum(MIN_DISTANCE_M, np.asarray(d, float))
    extra = np.maximum(0.0, 15.0 * np.log10(d) - 41.0)
    if min(h_tx, h_rx) > h_blocker:
        return np.zeros_like(d), np.zeros_like(d)
    if max(h_tx, h_rx) < h_blocker:
        return 9.0 + extra, np.full_like(d, 4.5)
    return 5.0 + extra, np.full_like(d, 4.0)


def shadowing_sigma_db(los_class):
    return np.where(np.asarray(los_class) == 0, 3.0, 4.0)


def _clipped_mean(mu, sigma):
    """E[max(0, X)], X ~ N(mu, sigma): the mean of the blockage loss the C++ clips at 0 dB."""
    sigma = np.maximum(sigma, 1e-9)
    z = mu / sigma
    return mu * ndtr(z) + sigma * np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)


def class_gain_moments(scenario, d3, fc_hz, heights=(ANTENNA_HEIGHT_M, BLOCKER_HEIGHT_M)):
    """Mean and standard deviation (both (n, 3)) of the gain in dB in each state."""
    d3 = np.asarray(d3, float)
    mean = np.stack([-pathloss_db(scenario, c, d3, fc_hz) for c in range(3)], axis=1)
    sigma = np.stack([np.broadcast_to(shadowing_sigma_db(c), d3.shape) for c in range(3)], axis=1).astype(float)
    b_mu, b_sigma = nlosv_blockage(d3, heights[0], heights[0], heights[1])
    mean[:, 1] -= _clipped_mean(b_mu, b_sigma)
    sigma[:, 1] = np.sqrt(sigma[:, 1] ** 2 + b_sigma ** 2)  # the clipping at 0 dB is ignored here
    return mean, sigma


def floored_mean(mu, sigma, floor):
    """E[max(X, floor)], X ~ N(mu, sigma): the traced gains are floored at the sensitivity floor."""
    sigma = np.maximum(sigma, 1e-9)
    z = (mu - floor) / sigma
    return floor * ndtr(-z) + mu * ndtr(z) + sigma * np.exp(-0.5 * z * z) / np.sqrt(2 * np.pi)


def decode_probability(mean, sigma, weights, tx_power_dbm, required_dbm):
    """P(tx power + gain >= required) with the gain a mixture of normals: (n, k) mean, sigma,
    weights; this is P(decoded) under log-normal shadowing (required = the larger of the
    sensitivity and noise + interference + SINR threshold)."""
    margin = (np.asarray(tx_power_dbm, float) - np.asarray(required_dbm, float))[:, None]
    return np.sum(weights * ndtr((margin + mean) / np.maximum(sigma, 1e-9)), axis=1)


class Tr37885:
    """TR 37.885 predictions for a block of links; true_class: use the traced LoS class instead
    of the distance-based state probabilities (the `tr37885+true-los` baseline)."""

    def __init__(self, scenario, fc_hz, heights=(ANTENNA_HEIGHT_M, BLOCKER_HEIGHT_M)):
        self.scenario, self.fc_hz, self.heights = scenario, fc_hz, heights

    def probabilities(self, d2, true_class=None):
        if true_class is None:
            return class_probabilities(self.scenario, d2)
        return np.eye(3)[np.asarray(true_class, int)]

    def predict(self, d2, d3, floor_db, true_class=None):
        """dict: proba (n, 3), cls (n,), gain_db (n,) expected floored gain, mean/sigma (n, 3)."""
        proba = self.probabilities(d2, true_class)
        mean, sigma = class_gain_moments(self.scenario, d3, self.fc_hz, self.heights)
        gain = np.sum(proba * floored_mean(mean, sigma, floor_db), axis=1)
        return {"proba": proba, "cls": np.argmax(proba, axis=1), "gain_db": gain, "mean": mean, "sigma": sigma}
