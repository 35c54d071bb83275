"""Training's parts; :mod:`surrogate.train` is the entry and names them all.

* :mod:`.losses`: the one-step loss of a batch (article 5.4.3: noise, mirror, pushforward);
* :mod:`.schedules`: the optimisers, their learning rates, the weight average and the epochs the schedules mark;
* :mod:`.phases`: one-step training and rollout fine-tuning, the two phases of a run;
* :mod:`.state`: what ``last.pt`` holds, how a run continues from it, and the run's other files;
* :mod:`.loop`: the epochs of a run's phases, their validation, early stopping and checkpoints.
"""
