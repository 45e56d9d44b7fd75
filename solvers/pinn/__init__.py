"""Physics-informed neural network adapters (`torch-pinn`, `jax-pinn`) for the swing equation.

The one specification both backends share: `config` the configuration and the named configs,
`architecture` the network layout, its flat parameter vector and seeded initial weights, `problems`
the seeded training points and loss weights, `model_file` the save/load format and its checks.
`network` the network, derivatives and loss over a backend's ops, `optim` the shared optimisers,
`common` the adapter base class; `torch_pinn` and `jax_pinn` the backends, each importing its
framework only inside itself (the registry reports a missing one as skipped).
"""
