#!/bin/sh
# OpenCV's mcc chart detector (opencv-contrib), the peer of benches/chart_real_vs_mcc.py.
set -e
python3 -c 'import cv2, cv2.mcc' 2>/dev/null && exit 0
pip install -q opencv-contrib-python-headless || pip install -q --break-system-packages opencv-contrib-python-headless
python3 -c 'import cv2, cv2.mcc'
