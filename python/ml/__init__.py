"""ML benchmark of raysweep datasets: tasks, metrics, TR 37.885 baselines, learned models.

Run: PYTHONPATH=python python3 -m ml --city NAME=RUN_DIR [...] --out DIR; see python/ml/README.md.
"""
