"""The misfit and velocity-RMSE history of an inversion example's results file (/history, written by
examples/fwi_2d_common.hpp), as two panels side by side: shared by the plot_fwi_*.py scripts."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def plot_history(f, path, xlabel="BLMVM iteration", misfit_label="misfit (data of the band in use)"):
    """Writes path (PNG) from the open h5py file f."""
    it = np.asarray(f["history/iteration"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    a1.semilogy(it, np.asarray(f["history/misfit"]), "o-", ms=3)
    a1.set_xlabel(xlabel)
    a1.set_ylabel(misfit_label)
    a1.set_title("data misfit")
    a2.plot(it, np.asarray(f["history/rmse"]), "o-", ms=3)
    a2.set_xlabel(xlabel)
    a2.set_ylabel("RMSE of c against the true model (km/s)")
    a2.set_title("velocity error")
    fig.savefig(path, dpi=100)
