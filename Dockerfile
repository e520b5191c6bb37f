# fdir-service: the onboard fault monitor. Build: docker build -t fdir-service .
# Run:  docker run --rm --network host fdir-service --master udpin:0.0.0.0:14550 --gcs udpout:GCS_IP:14550
# (Not built on the development machine: it has no container engine.)
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 FDIR_CONFIG_DIR=/app/config \
    NUMBA_CACHE_DIR=/app/numba-cache
WORKDIR /app
COPY pyproject.toml README.md* ./
COPY fdir_service ./fdir_service
COPY sim_bridge ./sim_bridge
COPY config ./config
# the filter's numba kernels compiled into the image (`fdir run` loads them in ~0.5 s on a CPU of
# the build machine's model; numba keys its cache on the CPU, so elsewhere its start-up warm-up
# compiles them again, 10-30 s, into the same writable folder); from /tmp, so that the installed
# package is the one compiled, not the copy in /app
RUN pip install --no-cache-dir . \
    && cd /tmp && python -c "from fdir_service.service_config import load_service_config as c; \
from fdir_service.estimation.warm_up import warm_up; s = c(None); warm_up(s.filter, s.estimator)" \
    && useradd --system --home /data fdir && mkdir -p /data && chown fdir /data \
    && chown -R fdir /app/numba-cache
USER fdir
WORKDIR /data
EXPOSE 14550/udp
ENTRYPOINT ["fdir", "run"]
CMD ["--master", "udpin:0.0.0.0:14550"]
