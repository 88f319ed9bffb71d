"""Typed FastAPI dependencies: the service state, its parts and the caller's identity.

They are ``async`` because they do no I/O: FastAPI then resolves them on the event loop
instead of spending a thread-pool round trip on each.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.dispatch import Dispatcher
from app.settings import Settings
from app.state import ServiceState
from app.storage.session import Database


async def get_service(request: Request) -> ServiceState:
    """The service state created at start-up."""
    service: ServiceState = request.app.state.service
    return service


ServiceDep = Annotated[ServiceState, Depends(get_service)]


async def get_settings_dep(service: ServiceDep) -> Settings:
    """The settings the application was created with."""
    return service.settings


async def get_database_dep(service: ServiceDep) -> Database:
    """The job database."""
    return service.database


async def get_dispatcher(service: ServiceDep) -> Dispatcher:
    """The dispatcher that hands jobs to workers."""
    return service.dispatcher


async def get_owner(service: ServiceDep) -> str:
    """The caller's identity; a single default owner until API keys exist."""
    return service.settings.default_owner


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]
DatabaseDep = Annotated[Database, Depends(get_database_dep)]
DispatcherDep = Annotated[Dispatcher, Depends(get_dispatcher)]
OwnerDep = Annotated[str, Depends(get_owner)]
