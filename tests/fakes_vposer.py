"""A fake VPoser v2 for the tests: a small torch network with VPoser v2's layers and state_dict keys,
seeded random weights and BatchNorm statistics (no licensed data), written the ways users have it: a
PyTorch-Lightning ``.ckpt`` (``state_dict`` under ``vp_model.``, hyper-parameter objects, optimizer
states), a plain state_dict ``.pt``, or the extracted ``V02_05/`` folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np

HIDDEN, LATENT = 512, 32


class HyperParameters(dict):
    """Stands for Lightning's hyper-parameter object: a dict subclass with attributes. Its ``__reduce__``
    would leave a file behind if a reader ever ran it."""

    marker: str = ""

    def __reduce__(self):
        return (open, (self.marker, "w"))  # creates the file when called


def reference(seed: int = 0, hidden: int = HIDDEN, latent: int = LATENT):
    """A torch module with VPoser v2's architecture (eval mode) and random weights and statistics."""
    import torch
    from torch import nn

    class Head(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.mu = nn.Linear(hidden, latent)
            self.logvar = nn.Linear(hidden, latent)

        def forward(self, x):
            return self.mu(x)

    class Reference(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.encoder_net = nn.Sequential(
                nn.Flatten(),
                nn.BatchNorm1d(63),
                nn.Linear(63, hidden),
                nn.LeakyReLU(),
                nn.BatchNorm1d(hidden),
                nn.Dropout(0.1),
                nn.Linear(hidden, hidden),
                nn.Linear(hidden, hidden),
                Head(),
            )
            self.decoder_net = nn.Sequential(
                nn.Linear(latent, hidden),
                nn.LeakyReLU(),
                nn.Dropout(0.1),
                nn.Linear(hidden, hidden),
                nn.LeakyReLU(),
                nn.Linear(hidden, 126),
            )

        def encode(self, pose):
            return self.encoder_net(pose)

        def decode_rotations(self, z):
            six = self.decoder_net(z).reshape(-1, 3, 2)
            r1 = torch.nn.functional.normalize(six[:, :, 0], dim=1)
            r2 = six[:, :, 1] - (r1 * six[:, :, 1]).sum(1, keepdim=True) * r1
            r2 = torch.nn.functional.normalize(r2, dim=1)
            return torch.stack([r1, r2, torch.linalg.cross(r1, r2)], dim=-1).reshape(len(z), 21, 3, 3)

    torch.manual_seed(seed)
    net = Reference()
    with torch.no_grad():
        for bn in (net.encoder_net[1], net.encoder_net[4]):
            bn.running_mean.normal_(0.0, 0.3)
            bn.running_var.uniform_(0.3, 2.0)
            bn.weight.uniform_(0.5, 1.5)
            bn.bias.normal_(0.0, 0.1)
    return net.eval()


def write_checkpoint(path: Path, net, marker: Path | None = None) -> Path:
    """A Lightning-style ``.ckpt``: weights under ``vp_model.``, a body model buffer, hyper-parameters,
    optimizer states."""
    import torch

    state = {f"vp_model.{k}": v for k, v in net.state_dict().items()}
    state["bm_train.v_template"] = torch.zeros(4, 3)  # human_body_prior's trainer keeps its body model here
    hyper = HyperParameters(latentD=LATENT, num_neurons=HIDDEN)
    hyper.marker = str(marker or path.with_suffix(".ran"))
    optimizer = torch.optim.Adam(net.parameters())
    checkpoint = {
        "epoch": 13,
        "global_step": 1234,
        "pytorch-lightning_version": "1.2.0",
        "state_dict": state,
        "hyper_parameters": hyper,
        "optimizer_states": [optimizer.state_dict()],
        "callbacks": {HyperParameters: {"best_model_score": torch.tensor(0.03)}},
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)
    return path


def write_folder(root: Path, net) -> Path:
    """The extracted ``V02_05/`` layout: ``snapshots/V02_05_epoch=13_val_loss=0.03.ckpt``."""
    write_checkpoint(root / "snapshots" / "V02_05_epoch=13_val_loss=0.03.ckpt", net, root / "ran")
    (root / "V02_05.yaml").write_text("model_params:\n  num_neurons: 512\n  latentD: 32\n")
    return root


def state_arrays(net) -> dict[str, np.ndarray]:
    return {k: v.detach().numpy() for k, v in net.state_dict().items()}
