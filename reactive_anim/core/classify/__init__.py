"""Classify at C: the classifier's features, the capture point, the outcome rule and the ONNX classifier."""
