"""The service's web pages: the caller's jobs and one job's page (status, live progress, plots,
verification, links to its JSON and CSV). Static files of this package, no CDN: they work on a
machine without internet."""
