"""Job storage: SQLAlchemy models, session factory, migrations and repository functions."""
