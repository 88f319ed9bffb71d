"""Typed FastAPI dependencies: the service state, its parts and the caller's identity."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.dispatch import Dispatcher
from app.settings import Settings
from app.state import ServiceState
from app.storage.session import Database


def get_service(request: Request) -> ServiceState:
    """The service state created at start-up."""
    service: ServiceState = request.app.state.service
    return service


ServiceDep = Annotated[ServiceState, Depends(get_service)]


def get_settings_dep(service: ServiceDep) -> Settings:
    """The settings the application was created with."""
    return service.settings


def get_database_dep(service: ServiceDep) -> Database:
    """The job database."""
    return service.database


def get_dispatcher(service: ServiceDep) -> Dispatcher:
    """The dispatcher that hands jobs to workers."""
    return service.dispatcher


def get_owner(service: ServiceDep) -> str:
    """The caller's identity; a single default owner until API keys exist."""
    return service.settings.default_owner


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
DatabaseDep = Annotated[Database, Depends(get_database_dep)]
DispatcherDep = Annotated[Dispatcher, Depends(get_dispatcher)]
OwnerDep = Annotated[str, Depends(get_owner)]
