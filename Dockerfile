# fdir-service: the onboard fault monitor. Build: docker build -t fdir-service .
# Run:  docker run --rm --network host fdir-service --master udpin:0.0.0.0:14550 --gcs udpout:GCS_IP:14550
# (Not built on the development machine: it has no container engine.)
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 FDIR_CONFIG_DIR=/app/config
WORKDIR /app
COPY pyproject.toml README.md* ./
COPY fdir_service ./fdir_service
COPY sim_bridge ./sim_bridge
COPY config ./config
RUN pip install --no-cache-dir . \
    && useradd --system --home /data fdir && mkdir -p /data && chown fdir /data
USER fdir
WORKDIR /data
EXPOSE 14550/udp
ENTRYPOINT ["fdir", "run"]
CMD ["--master", "udpin:0.0.0.0:14550"]
