#!/usr/bin/env bash
# Installs the leanest torch that runs on this project's machines (CPU only) into the active
# Python environment, for the camera/YOLO tests (the `yolo` extra of usvfast).
#
# Only PyPI is reachable, and PyPI's Linux x86_64 torch wheel is a CUDA build whose shared
# libraries are hard-linked against CUDA runtime libraries (libcudart, cuBLAS, cuDNN, NCCL, ...):
# `pip install torch --no-deps` alone fails at `import torch`. A plain `pip install torch` pulls
# ~5 GB (triton, cuda-bindings, cuSOLVER, NVTX, ... as well). This script installs the torch
# wheel without its dependency resolution, plus exactly the CUDA libraries its .so files link
# against and its small pure-Python dependencies. CUDA is never initialised on a machine
# without a GPU; everything runs on the CPU.
#
# Usage: .ci/install-torch.sh [python]   (default: python on PATH)
# Measured on a fresh venv here: 2 min 55 s, 4.0 GB installed (plain `pip install torch`:
# 5 min 9 s, 5.3 GB). Idempotent: exits at once when torch already imports.
set -euo pipefail
PY="${1:-python}"
if "$PY" -c "import torch" 2>/dev/null; then
    echo "torch already importable: $("$PY" -c 'import torch; print(torch.__version__)')"
    exit 0
fi
"$PY" -m pip install -q --no-warn-conflicts --no-deps \
    "torch==2.15.0" \
    "nvidia-cuda-runtime==13.2.86.*" "nvidia-cublas==13.4.1.3.*" "nvidia-cufft==12.2.0.57.*" \
    "nvidia-cufile==1.17.1.22.*" "nvidia-cusparse==12.7.10.12.*" "nvidia-nvjitlink==13.2.86.*" \
    "nvidia-cuda-nvrtc==13.2.86.*" "nvidia-cudnn-cu13==9.26.0.51" "nvidia-cusparselt-cu13==0.8.1" \
    "nvidia-nccl-cu13==2.30.7" "nvidia-nvshmem-cu13==3.7.2" "nvidia-cuda-cupti==13.2.86.*"
"$PY" -m pip install -q --no-warn-conflicts filelock "typing-extensions>=4.13" "sympy>=1.13.3" "networkx>=2.5.1" \
    jinja2 "fsspec>=0.8.5"
"$PY" -c "import torch; torch.nn.Conv2d(3, 4, 3)(torch.zeros(1, 3, 8, 8)); print('torch', torch.__version__, 'ok (CPU)')"
