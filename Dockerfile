# PickStop: the API, the 3D planner and Dask workers share this image (see docker-compose.yml).
FROM python:3.11-slim
ENV PYTHONUNBUFFERED=1 OPENBLAS_NUM_THREADS=1 PICKSTOP_DATA_DIR=/data PICKSTOP_CACHE_DIR=/data/cache
WORKDIR /app
# Dependencies first (from pyproject.toml), so code changes reuse the layer.
COPY pyproject.toml README.md ./
COPY backend backend
COPY frontend frontend
COPY database database
COPY examples examples
RUN pip install --no-cache-dir -e ".[dask]"
VOLUME /data
EXPOSE 8000 8080 8786
CMD ["pickstop", "serve", "--host", "0.0.0.0", "--no-ui"]
