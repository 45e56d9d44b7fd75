"""Physics-informed neural network adapters (`torch-pinn`, `jax-pinn`) for the swing equation.

`spec` holds the one specification (configuration, sampling, initial weights, loss weights,
save/load format), `network` the network, derivatives and loss over a backend's ops, `optim` the
shared optimisers, `common` the adapter base class; `torch_pinn` and `jax_pinn` the backends,
each importing its framework only inside itself (the registry reports a missing one as skipped).
"""
