"""Networks trained on ikbench's own dataset (``ikbench learn``, issue 61): its room of its
own, above the studies whose datasets it reads (:mod:`ikbench.learned.train`: training, the
model file, :func:`~ikbench.learned.train.load_model`; :mod:`ikbench.learned.model`: the
networks and the loaded model's ``propose``, ``predict``, ``error``)."""
